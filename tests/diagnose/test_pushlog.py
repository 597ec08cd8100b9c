"""Push-log parsing for `imply diagnose`: every bad cell is an error naming its row and column."""

from __future__ import annotations

import pytest

from imply.cli import main
from imply.diagnose.inputs.pushlog import read_pushlog
from imply.input_files import InputError
from sample_inputs import PUSHLOG_CSV

GOOD = PUSHLOG_CSV


def _write(tmp_path, text: str, name: str = "log.csv"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_good_log_parses(tmp_path):
    log = read_pushlog(_write(tmp_path, GOOD), (0.15, 1.05))
    assert log.objects == ["a", "b"]
    assert log.n == 6 and log.has_direction
    assert list(log.obj) == [0, 0, 0, 1, 1, 1]


@pytest.mark.parametrize(
    "edit, expected",
    [
        (
            lambda t: t.replace("object_id,speed,displacement", "object_id,velocity,displacement"),
            "missing column(s) speed",
        ),
        (lambda t: t.replace("a,0.5,0.09", "a,fast,0.09"), "row 2 (line 3), column speed"),
        (lambda t: t.replace("b,0.5,0.07", "b,0.5,-0.07"), "row 5 (line 6), column displacement: -0.07 is negative"),
        (lambda t: t.replace("b,0.5,0.07", "b,0.5,0"), "column displacement: is 0"),
        (lambda t: t.replace("a,0.7,0.14,3.14", "a,0.7,0.14,north"), "row 3 (line 4), column direction"),
        (lambda t: t.replace("a,0.7,0.14,3.14", "a,0.7,0.14,90"), "column direction: 90 is not an angle in radians"),
        (lambda t: t.replace("b,0.7,0.10", "b,1.7,0.10"), "row 6 (line 7), column speed: 1.7 is outside"),
        (lambda t: t.replace("b,0.3,0.04", ",0.3,0.04"), "row 4 (line 5), column object_id: is empty"),
        (lambda t: t.replace("b,0.5,0.07,0\nb,0.7,0.10,0\n", ""), "object 'b' has 1 push(es)"),
        (lambda t: t.replace("a,0.3,0.05,0", "a,0.3,nan,0"), "row 1 (line 2), column displacement"),
    ],
)
def test_bad_cells_are_named(tmp_path, edit, expected):
    with pytest.raises(InputError) as err:
        read_pushlog(_write(tmp_path, edit(GOOD)), (0.15, 1.05))
    assert expected in str(err.value)


def test_size_columns_come_together_and_ok_false_is_refused(tmp_path):
    text = (
        GOOD.replace("direction\n", "direction,size_x\n", 1)
        .replace("\n", ",0.05\n")
        .replace("direction,size_x,0.05", "direction,size_x")
    )
    with pytest.raises(InputError, match="missing size_y, size_z"):
        read_pushlog(_write(tmp_path, text), None)
    text = GOOD.replace("direction\n", "direction,ok\n", 1)
    lines = text.splitlines()
    lines = [lines[0]] + [ln + (",False" if i == 2 else ",True") for i, ln in enumerate(lines[1:])]
    with pytest.raises(InputError, match="row 3 .*column ok"):
        read_pushlog(_write(tmp_path, "\n".join(lines) + "\n"), None)


def test_cli_bad_log_exits_2_without_output(tmp_path, tiny_table_path, capsys):
    bad = _write(tmp_path, GOOD.replace("a,0.5,0.09", "a,0.5,-1"))
    out = tmp_path / "report"
    code = main(
        ["diagnose", str(bad), "--table", str(tiny_table_path), "--cache-dir", str(tmp_path / "c"), "-o", str(out)]
    )
    assert code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "column displacement" in err[0]
    assert not out.exists() and not (tmp_path / "c").exists()  # refused before any simulation


def test_measured_mass_must_be_constant_per_object_and_in_range(tmp_path):
    text = GOOD.replace("direction\n", "direction,mass\n", 1)
    lines = text.splitlines()
    masses = ["0.5", "0.5", "0.5", "1.0", "1.0", "1.0"]
    good = "\n".join([lines[0]] + [f"{ln},{m}" for ln, m in zip(lines[1:], masses, strict=True)]) + "\n"
    log = read_pushlog(_write(tmp_path, good), (0.15, 1.05), mass_range=(0.2, 2.0))
    assert list(log.mass) == [0.5, 1.0] and log.friction is None
    masses[4] = "1.1"
    bad = "\n".join([lines[0]] + [f"{ln},{m}" for ln, m in zip(lines[1:], masses, strict=True)]) + "\n"
    with pytest.raises(InputError, match="row 5 .*column mass: differs"):
        read_pushlog(_write(tmp_path, bad), (0.15, 1.05))
    masses[3:] = ["3.0"] * 3
    far = "\n".join([lines[0]] + [f"{ln},{m}" for ln, m in zip(lines[1:], masses, strict=True)]) + "\n"
    with pytest.raises(InputError, match="row 4 .*column mass: 3 is outside the table's range"):
        read_pushlog(_write(tmp_path, far), (0.15, 1.05), mass_range=(0.2, 2.0))


def _with_pusher_speed(text: str, values: list[str]) -> str:
    lines = text.strip().split("\n")
    out = [lines[0] + ",pusher_speed"] + [f"{row},{v}" for row, v in zip(lines[1:], values, strict=True)]
    return "\n".join(out) + "\n"


def test_pusher_speed_is_read_and_its_bad_cells_named(tmp_path):
    good = _with_pusher_speed(GOOD, ["0.2", "0.3", "0.4", "0.2", "0.3", "0.4"])
    log = read_pushlog(_write(tmp_path, good), (0.15, 1.05))
    assert log.pusher_speed.tolist() == [0.2, 0.3, 0.4, 0.2, 0.3, 0.4]
    assert (
        log.aux("pusher_speed") is not None
        and read_pushlog(_write(tmp_path, GOOD), (0.15, 1.05)).aux("pusher_speed") is None
    )
    for values, expected in (
        (["0.2", "0.3", "-0.4", "0.2", "0.3", "0.4"], "row 3 (line 4), column pusher_speed: -0.4 must be positive"),
        (["0.2", "0.3", "0.4", "0.2", "300", "0.4"], "row 5 (line 6), column pusher_speed: 300 m/s is more than"),
        (["0.2", "0.3", "0.4", "fast", "0.3", "0.4"], "row 4 (line 5), column pusher_speed"),
    ):
        with pytest.raises(InputError) as err:
            read_pushlog(_write(tmp_path, _with_pusher_speed(GOOD, values)), (0.15, 1.05))
        assert expected in str(err.value)
