"""The box's track beside a push log: read into crossing times, every bad row refused with one line naming it."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imply.cli import main
from imply.diagnose.inputs.pushlog import read_pushlog
from imply.diagnose.inputs.track_file import read_track, track_beside
from imply.input_files import InputError
from sample_inputs import PUSHLOG_CSV

FRAMES = 40
RATE = 100.0


def _log(tmp_path, text: str = PUSHLOG_CSV):
    path = tmp_path / "log.csv"
    path.write_text(text)
    return read_pushlog(path, (0.15, 1.05))


def _track(log) -> pd.DataFrame:
    """A box that decelerates uniformly along each push's direction to the log's displacement in 0.3 s."""
    rows = []
    t = np.arange(FRAMES) / RATE
    for i in range(log.n):
        d, phi = log.displacement[i], log.direction[i]
        s = np.where(t < 0.3, d * (1.0 - (1.0 - t / 0.3) ** 2), d)
        rows.append(
            pd.DataFrame(
                {
                    "object_id": log.objects[log.obj[i]],
                    "push": i + 1,
                    "t": t,
                    "x": 0.2 + s * np.cos(phi),
                    "y": -0.1 + s * np.sin(phi),
                }
            )
        )
    return pd.concat(rows, ignore_index=True)


def _write(tmp_path, frame: pd.DataFrame):
    path = tmp_path / "log.track.csv"
    frame.to_csv(path, index=False)
    return path


def test_a_track_gives_each_push_the_times_it_covers_fractions_of_its_travel(tmp_path):
    """Uniform deceleration over 0.3 s covers a quarter of the travel at 0.3 (1 - sqrt(0.75)) s, half at
    0.3 (1 - sqrt(0.5)) s, three quarters at 0.15 s, whatever the direction and the origin of the frame."""
    log = _log(tmp_path)
    path = _write(tmp_path, _track(log))
    assert track_beside(tmp_path / "log.csv") == str(path)
    tracked = read_track(path, log)
    expected = 0.3 * (1.0 - np.sqrt(1.0 - np.array([0.25, 0.5, 0.75])))
    np.testing.assert_allclose(tracked.crossing_times, np.tile(expected, (log.n, 1)), atol=2e-3)
    np.testing.assert_allclose(tracked.aux("crossing_50"), np.log(tracked.crossing_times[:, 1]))
    assert log.aux("crossing_50") is None and tracked.track_path == str(path)


def _edit_row(frame: pd.DataFrame, row: int, **values) -> pd.DataFrame:
    frame = frame.copy()
    for k, v in values.items():
        frame.loc[row, k] = v
    return frame


@pytest.mark.parametrize(
    "edit, expected",
    [
        (lambda f: _edit_row(f, 5, t=0.01), "row 6 (line 7), column t: 0.01 does not come after the frame before it"),
        (
            lambda f: f.assign(t=np.where(f["push"] == 2, f["t"] + 0.5, f["t"])),
            f"row {FRAMES + 1} (line {FRAMES + 2}), column t: the track of push 2 starts at 0.5 s",
        ),
        (
            lambda f: _edit_row(f, FRAMES + 3, object_id="b"),
            f"row {FRAMES + 4} (line {FRAMES + 5}), column object_id: 'b', but push 2 of the log is of 'a'",
        ),
        (lambda f: f[f["push"] != 4], "row 4 (line 5): push 4 has no track in"),
        (
            lambda f: f.assign(push=np.where(f["push"] == 6, 9, f["push"])),
            f"row {5 * FRAMES + 1} (line {5 * FRAMES + 2}), column push: 9 is not a push of",
        ),
        (
            lambda f: f.assign(x=np.where(f["push"] == 3, f["x"] * 0 + 0.2, f["x"])),
            f"row {3 * FRAMES} (line {3 * FRAMES + 1}), column x: the track of push 3 ends 0 m along the push",
        ),
        (
            lambda f: f.assign(y=np.where(f["push"] == 6, f["x"], f["y"]), x=np.where(f["push"] == 6, 0.2, f["x"])),
            "the track of push 6 ends 0 m along the push",
        ),  # filmed across the log's direction
        (
            lambda f: f.assign(x=f["x"] * 1000, y=f["y"] * 1000),
            "ends 50 m along the push from where it starts; the log's displacement is 0.05 m",
        ),
        (
            lambda f: pd.concat(
                [f.iloc[: FRAMES // 2], f.iloc[FRAMES : 2 * FRAMES], f.iloc[FRAMES // 2 : FRAMES], f.iloc[2 * FRAMES :]]
            ),
            f"row {2 * FRAMES - FRAMES // 2 + 1} (line {2 * FRAMES - FRAMES // 2 + 2}), column push: push 1 continues here",
        ),
        (lambda f: pd.concat([f[f["push"] != 1], f[f["push"] == 1].iloc[:3]]), "the track of push 1 has 3 frame(s)"),
        (lambda f: _edit_row(f.astype({"y": object}), 7, y="left"), "row 8 (line 9), column y: 'left' is not a finite"),
        (lambda f: f.drop(columns=["t"]), "missing column(s) t"),
    ],
)
def test_a_bad_track_is_refused_naming_its_row(tmp_path, edit, expected):
    log = _log(tmp_path)
    with pytest.raises(InputError) as err:
        read_track(_write(tmp_path, edit(_track(log))), log)
    assert expected in str(err.value) and "\n" not in str(err.value), str(err.value)


def test_a_track_names_pushes_by_the_logs_push_column_where_it_has_one(tmp_path):
    lines = PUSHLOG_CSV.strip().splitlines()
    numbered = "\n".join([lines[0] + ",push"] + [f"{row},{10 * (i + 1)}" for i, row in enumerate(lines[1:])]) + "\n"
    log = _log(tmp_path, numbered)
    track = _track(log).assign(push=lambda f: f["push"] * 10)
    assert np.isfinite(read_track(_write(tmp_path, track), log).crossing_times).all()
    twice = numbered.replace("b,0.5,0.07,0,50", "b,0.5,0.07,0,40")
    with pytest.raises(InputError, match=r"row 5 \(line 6\), column push: 40 names an earlier push too"):
        _log(tmp_path, twice)


def test_imply_diagnose_refuses_a_bad_track_before_any_work(tmp_path, tiny_table_path, capsys):
    log = _log(tmp_path)
    bad = _write(tmp_path, _edit_row(_track(log), 5, t=0.01))
    code = main(
        [
            "diagnose",
            str(tmp_path / "log.csv"),
            "--table",
            str(tiny_table_path),
            "--track",
            str(bad),
            "-o",
            str(tmp_path / "report"),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert code != 0 and "row 6 (line 7), column t" in err and len(err.splitlines()) == 1, err
    assert not (tmp_path / "report").exists()


def test_a_push_too_short_to_time_leaves_the_track_out_and_says_why(tmp_path):
    """A box that moved less than a camera's few millimetres has a track of noise: the log keeps its pushes and
    loses its track, with the reason; a push that moved far with an untimed track is still refused."""
    lines = PUSHLOG_CSV.strip().splitlines()
    lines[4] = "b,0.3,0.0008,0"  # push 4 moved 0.8 mm
    log = _log(tmp_path, "\n".join(lines) + "\n")
    track = _track(log)
    track.loc[track["push"] == 4, "x"] = 0.2  # within the camera's resolution, the box never moved
    tracked = read_track(_write(tmp_path, track), log)
    assert tracked.crossing_times is None and tracked.aux("crossing_50") is None
    assert "push 4 moved 0.0008 m" in tracked.track_note
    # the same track for a push that moved 4 cm is refused
    far = _log(tmp_path)
    track = _track(far)
    track.loc[track["push"] == 4, "x"] = 0.2
    with pytest.raises(InputError, match="the track of push 4"):
        read_track(_write(tmp_path, track), far)
