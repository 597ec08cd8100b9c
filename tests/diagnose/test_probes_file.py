"""The calibration probes beside a push log: read, checked row by row, refused with one line naming the row."""

from __future__ import annotations

import numpy as np
import pytest

from imply.diagnose.inputs.probes import DEFAULT_FRICTION_SD, read_probes
from imply.input_files import InputError

HEADER = "probe,object_id,speed,direction,pusher_speed,displacement,stop_time,added_mass,friction,friction_sd"
GOOD = [
    "free_stroke,,0.3,,0.28,,,,,",
    "free_stroke,,0.9,,0.75,,,,,",
    "friction,a,0.1,2.5,,,,,0.31,0.04",
    "friction,b,,,,,,,0.2,",
    "added_mass,a,0.3,0.5,0.25,0.02,0.15,0.25,,",
    "added_mass,b,0.9,,,0.1,,0.4,,",
]


def _read(tmp_path, rows, **kw):
    path = tmp_path / "log.probes.csv"
    path.write_text("\n".join([HEADER, *rows]) + "\n")
    return read_probes(path, objects=["a", "b"], log_path="log.csv", speed_range=(0.15, 1.05), **kw)


def test_a_good_file_is_read_into_arrays(tmp_path):
    p = _read(tmp_path, GOOD)
    assert p.counts() == {"free_stroke": 2, "friction": 2, "added_mass": 2}
    assert np.allclose(p.free_stroke_pusher_speed, [0.28, 0.75])
    assert np.allclose(p.friction, [0.31, 0.2]) and np.allclose(p.friction_sd, [0.04, DEFAULT_FRICTION_SD])
    assert p.added_obj.tolist() == [0, 1] and np.allclose(p.added_mass, [0.25, 0.4])
    assert np.isnan(p.added_stop_time[1]) and p.added_direction[0] == 0.5
    # a pull test's drag: its own speed (slower than the table's pushes) and direction, where the row says them
    assert p.friction_speed[0] == 0.1 and p.friction_direction[0] == 2.5
    assert np.isnan(p.friction_speed[1]) and np.isnan(p.friction_direction[1])


@pytest.mark.parametrize(
    ("row", "match"),
    [
        ("friction_test,a,,,,,,,0.3,", r"row 7 \(line 8\), column probe: 'friction_test' is not a probe"),
        ("friction,c,,,,,,,0.3,", r"row 7 \(line 8\), column object_id: 'c' is not an object of log.csv"),
        ("friction,,,,,,,,0.3,", r"column object_id: is empty; a friction probe names its object"),
        ("added_mass,a,0.5,,,0.05,,,,", r"column added_mass: is empty; a added_mass probe needs it"),
        ("free_stroke,,0.5,,fast,,,,,", r"column pusher_speed: 'fast' is not a number"),
        ("free_stroke,,1.5,,0.4,,,,,", r"column speed: 1.5 is outside the table's speed range"),
        ("free_stroke,,0.5,,1.4,,,,,", r"column pusher_speed: 1.4 m/s is more than twice the commanded speed"),
        ("added_mass,a,0.5,,,0.05,,-0.1,,", r"column added_mass: -0.1 must be positive"),
        ("friction,a,,,,,,,0.3,", r"row 7 \(line 8\), column object_id: 'a' has a friction measurement in an earlier"),
        ("friction,a,-0.1,,,,,,0.3,", r"row 7 \(line 8\), column speed: -0.1 must be positive"),
    ],
)
def test_bad_rows_are_refused_naming_row_and_column(tmp_path, row, match):
    with pytest.raises(InputError, match=match):
        _read(tmp_path, [*GOOD, row])


def test_a_loaded_box_must_stay_in_the_table_s_mass_range(tmp_path):
    with pytest.raises(InputError, match=r"row 5 \(line 6\), column added_mass: the loaded box weighs 2.15 kg"):
        _read(tmp_path, GOOD, mass=np.array([1.9, 0.5]), mass_range=(0.2, 2.0))
