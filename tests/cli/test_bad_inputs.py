"""Every user-facing command under hostile input: one line naming the fault, exit 2, nothing written.

Each case runs in a folder holding good inputs and a bystander file; the folder must be
byte for byte the same afterwards (no output, no temporary file, nothing deleted).
"""

from __future__ import annotations

import hashlib
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from imply.cli import main
from sample_inputs import PUSHLOG_CSV, ROLLOUTS_CSV

ROLLOUTS = ROLLOUTS_CSV

PUSHLOG = PUSHLOG_CSV

PUSHES = "object_id,speed\nx,0.3\nx,0.6\n"
GRID = (
    '{"speeds": {"min": 0.15, "max": 1.05, "n": 4}, "masses": {"min": 0.2, "max": 2.0, "n": 4}, '
    '"frictions": {"min": 0.1, "max": 0.6, "n": 4}}'
)


def _rollouts(old: str, new: str) -> dict[str, str]:
    assert old in ROLLOUTS, old
    return {"r.csv": ROLLOUTS.replace(old, new)}


def _pushlog(old: str, new: str) -> dict[str, str]:
    assert old in PUSHLOG, old
    return {"log.csv": PUSHLOG.replace(old, new)}


def _with_column(text: str, name: str, values: list[str]) -> str:
    lines = text.strip().splitlines()
    return "\n".join([f"{lines[0]},{name}"] + [f"{ln},{v}" for ln, v in zip(lines[1:], values, strict=True)]) + "\n"


SCORE = ["score", "r.csv", "--table", "table.npz", "-o", "scores.csv"]
DIAGNOSE = ["diagnose", "log.csv", "--table", "table.npz", "--cache-dir", "cache", "-o", "report"]
EXPORT = ["sim", "export-xml", "-o", "box.xml"]
BUILD = ["table", "build", "-o", "t.npz"]
PUSH = ["sim", "pushes", "pushes.csv", "-o", "pushlog_out.csv"]

# (id, argv, files written over the good ones, expected part of the one-line message)
CASES = [
    # -- imply score: the rollouts file ------------------------------------------------
    ("score-missing-column", SCORE, _rollouts("displacement", "disp"), "missing column(s) displacement"),
    ("score-text-speed", SCORE, _rollouts("b,rollout,0.4", "b,rollout,fast"), "row 6 (line 7), column speed"),
    ("score-nan", SCORE, _rollouts("b,rollout,0.4,0.05", "b,rollout,0.4,nan"), "row 6 (line 7), column displacement"),
    ("score-inf", SCORE, _rollouts("b,rollout,0.4,0.05", "b,rollout,0.4,inf"), "column displacement: 'inf' is not"),
    ("score-empty-cell", SCORE, _rollouts("b,rollout,0.4,0.05", "b,rollout,,0.05"), "row 6 (line 7), column speed"),
    ("score-negative", SCORE, _rollouts("b,rollout,0.4,0.05", "b,rollout,0.4,-0.05"), "-0.05 is negative"),
    ("score-speed-outside", SCORE, _rollouts("b,rollout,0.4", "b,rollout,3.0"), "column speed: 3 is outside"),
    ("score-speed-below", SCORE, _rollouts("b,rollout,0.4", "b,rollout,0.01"), "column speed: 0.01 is outside"),
    ("score-role", SCORE, _rollouts("b,rollout,0.4", "b,prediction,0.4"), "row 6 (line 7), column role"),
    ("score-one-rollout", SCORE, _rollouts("b,rollout,0.7,0.11\n", ""), "object 'b' has 1 rollout(s)"),
    (
        "score-only-calibration",
        SCORE,
        {"r.csv": "object_id,role,speed,displacement\nq,calibration,0.3,0.03\n"},
        "object 'q' has 0 rollout(s)",
    ),
    (
        "score-empty-id",
        SCORE,
        _rollouts("b,rollout,0.4", " ,rollout,0.4"),
        "row 6 (line 7), column object_id: is empty",
    ),
    (
        "score-duplicate-row",
        SCORE,
        _rollouts("b,rollout,0.7,0.11\n", "b,rollout,0.7,0.11\nb,rollout,0.7,0.11\n"),
        "row 7 (line 8) and row 8 (line 9): object 'b' has two rollout rows at speed 0.7",
    ),
    (
        "score-same-speed",
        SCORE,
        _rollouts("a,rollout,0.85,0.18", "a,rollout,0.55,0.09"),
        "row 4 (line 5) and row 5 (line 6): object 'a' has two rollout rows at speed 0.55",
    ),
    (
        "score-duplicate-after-strip",
        SCORE,
        _rollouts("a,rollout,0.85,0.18", "a ,rollout,0.55,0.09"),
        "object 'a' has two rollout rows at speed 0.55",
    ),
    (
        "score-duplicate-calibration",
        SCORE,
        _rollouts("a,calibration,0.8,0.16", "a,calibration,0.3,0.04"),
        "object 'a' has two calibration rows at speed 0.3",
    ),
    (
        "score-blank-line",
        SCORE,
        _rollouts("a,rollout,0.25,0.03\n", "\na,rollout,0.25,oops\n"),
        "row 3 (line 5), column displacement",
    ),
    (
        "score-quoted-newline",
        SCORE,
        _rollouts("a,rollout,0.25,0.03\n", '"a\nb",rollout,0.25,0.03\n'),
        "object 'a\\nb' has 1 rollout(s)",
    ),
    ("score-header-only", SCORE, {"r.csv": "object_id,role,speed,displacement\n"}, "no data rows"),
    ("score-empty-file", SCORE, {"r.csv": ""}, "r.csv: cannot read as a CSV table"),
    ("score-ragged", SCORE, _rollouts("b,rollout,0.4,0.05", "b,rollout,0.4,0.05,9"), "r.csv: cannot read"),
    ("score-binary", SCORE, {"r.csv": b"\x89PNG\r\n\x1a\n\x00\x00\xff\xfe"}, "r.csv: cannot read"),
    (
        "score-no-rollouts-file",
        ["score", "none.csv", "--table", "table.npz", "-o", "s.csv"],
        {},
        "none.csv: no such file",
    ),
    ("score-rollouts-folder", ["score", "sub", "--table", "table.npz", "-o", "s.csv"], {}, "sub: is a directory"),
    (
        "score-parquet-cell",
        ["score", "r.parquet", "--table", "table.npz", "-o", "s.csv"],
        {"r.parquet": "nan-speed"},
        "r.parquet: row 2, column speed: nan is not a finite number",
    ),
    # -- imply score: the table and the options -----------------------------------------
    (
        "score-no-table",
        ["score", "r.csv", "--table", "none.npz", "-o", "s.csv"],
        {},
        "--table: table file none.npz does",
    ),
    (
        "score-table-folder",
        ["score", "r.csv", "--table", "sub", "-o", "s.csv"],
        {},
        "--table: table file sub is a folder",
    ),
    (
        "score-table-text",
        ["score", "r.csv", "--table", "notes.txt", "-o", "s.csv"],
        {},
        "--table: notes.txt is not a push table (expected the .npz file",
    ),
    (
        "score-table-other-npz",
        ["score", "r.csv", "--table", "other.npz", "-o", "s.csv"],
        {"other.npz": "npz"},
        "is not a push table: missing array(s)",
    ),
    ("score-grid-huge", [*SCORE, "--grid", "100000"], {}, "argument --grid: 100000 is out of range"),
    ("score-grid-small", [*SCORE, "--grid", "1"], {}, "argument --grid: 1 is out of range"),
    ("score-grid-text", [*SCORE, "--grid", "fine"], {}, "argument --grid: 'fine' is not an integer"),
    ("score-floor-zero", [*SCORE, "--floor", "0"], {}, "argument --floor: 0 must be a positive number"),
    ("score-floor-nan", [*SCORE, "--floor", "nan"], {}, "argument --floor: nan must be a positive number"),
    # -- imply score: where the output goes ----------------------------------------------
    (
        "score-output-is-input",
        ["score", "r.csv", "--table", "table.npz", "-o", "r.csv"],
        {},
        "-o r.csv is also an input",
    ),
    (
        "score-output-is-input-path",
        ["score", "r.csv", "--table", "table.npz", "-o", "./sub/../r.csv"],
        {},
        "is also an input",
    ),
    ("score-output-is-table", ["score", "r.csv", "--table", "table.npz", "-o", "table.npz"], {}, "is also an input"),
    ("score-output-folder", ["score", "r.csv", "--table", "table.npz", "-o", "sub"], {}, "-o sub is a folder"),
    (
        "score-output-under-file",
        ["score", "r.csv", "--table", "table.npz", "-o", "notes.txt/s.csv"],
        {},
        "notes.txt is a file, not a folder",
    ),
    (
        "score-output-unwritable",
        ["score", "r.csv", "--table", "table.npz", "-o", "/proc/imply/s.csv"],
        {},
        "/proc/imply/s.csv",
    ),
    # -- imply diagnose ------------------------------------------------------------------
    ("diag-missing-column", DIAGNOSE, _pushlog("object_id,speed", "object_id,velocity"), "missing column(s) speed"),
    ("diag-text-speed", DIAGNOSE, _pushlog("a,0.5,0.09", "a,fast,0.09"), "row 2 (line 3), column speed"),
    ("diag-zero-displacement", DIAGNOSE, _pushlog("b,0.5,0.07", "b,0.5,0"), "column displacement: is 0"),
    ("diag-negative-displacement", DIAGNOSE, _pushlog("b,0.5,0.07", "b,0.5,-0.07"), "-0.07 is negative"),
    ("diag-model-missing", [*DIAGNOSE, "--model", "scene.xml"], {}, "--model scene.xml: no such file"),
    (
        "diag-model-without-box",
        [*DIAGNOSE, "--model", "scene.xml"],
        {
            "scene.xml": '<mujoco><worldbody><body name="crate"><freejoint/><geom size="0.05"/></body></worldbody></mujoco>'
        },
        "has no body named 'box'",
    ),
    ("diag-negative-speed", DIAGNOSE, _pushlog("b,0.5,0.07", "b,-0.5,0.07"), "column speed: -0.5 must be positive"),
    ("diag-speed-outside", DIAGNOSE, _pushlog("b,0.7,0.10", "b,1.7,0.10"), "row 6 (line 7), column speed: 1.7 is"),
    ("diag-direction-text", DIAGNOSE, _pushlog("a,0.7,0.14,3.14", "a,0.7,0.14,north"), "column direction"),
    ("diag-direction-degrees", DIAGNOSE, _pushlog("a,0.7,0.14,3.14", "a,0.7,0.14,90"), "not an angle in radians"),
    ("diag-empty-id", DIAGNOSE, _pushlog("b,0.3,0.04", "  ,0.3,0.04"), "row 4 (line 5), column object_id: is empty"),
    ("diag-few-pushes", DIAGNOSE, _pushlog("b,0.5,0.07,0\nb,0.7,0.10,0\n", ""), "object 'b' has 1 push(es)"),
    (
        "diag-one-speed",
        DIAGNOSE,
        _pushlog("b,0.5,0.07,0\nb,0.7,0.10,0\n", "b,0.3,0.05,0\nb,0.3,0.04,0\n"),
        "object 'b' has 3 push(es) at 1 speed(s)",
    ),
    (
        "diag-blank-line",
        DIAGNOSE,
        _pushlog("a,0.5,0.09,1.57\n", "\n\na,0.5,-0.09,1.57\n"),
        "row 2 (line 5), column displacement",
    ),
    (
        "diag-stop-time",
        DIAGNOSE,
        {"log.csv": _with_column(PUSHLOG, "stop_time", ["1", "1", "-1", "1", "1", "1"])},
        "row 3 (line 4), column stop_time: -1 is negative",
    ),
    (
        "diag-size-partial",
        DIAGNOSE,
        {"log.csv": _with_column(PUSHLOG, "size_x", ["0.05"] * 6)},
        "missing size_y, size_z",
    ),
    (
        "diag-ok-false",
        DIAGNOSE,
        {"log.csv": _with_column(PUSHLOG, "ok", ["true"] * 2 + ["false"] + ["true"] * 3)},
        "row 3 (line 4), column ok",
    ),
    ("diag-ok-text", DIAGNOSE, {"log.csv": _with_column(PUSHLOG, "ok", ["yes"] * 6)}, "'yes' is not true/false"),
    (
        "diag-mass-varies",
        DIAGNOSE,
        {"log.csv": _with_column(PUSHLOG, "mass", ["0.5"] * 4 + ["1.1", "0.5"])},
        "row 5 (line 6), column mass: differs",
    ),
    (
        "diag-mass-outside",
        DIAGNOSE,
        {"log.csv": _with_column(PUSHLOG, "mass", ["3"] * 6)},
        "column mass: 3 is outside the table's range",
    ),
    (
        "diag-parquet-cell",
        [*DIAGNOSE[:1], "log.parquet", *DIAGNOSE[2:]],
        {"log.parquet": "negative-speed"},
        "log.parquet: row 4, column speed: -1 must be positive",
    ),
    ("diag-no-log", ["diagnose", "none.csv", "--table", "table.npz", "-o", "report"], {}, "none.csv: no such file"),
    ("diag-no-table", ["diagnose", "log.csv", "--table", "none.npz", "-o", "report"], {}, "--table: table file"),
    ("diag-table-text", ["diagnose", "log.csv", "--table", "notes.txt", "-o", "report"], {}, "is not a push table"),
    ("diag-effects", [*DIAGNOSE, "--effects", "tlit,viscous"], {}, "--effects: unknown effect(s): tlit"),
    ("diag-noise-sd", [*DIAGNOSE, "--noise-sd", "0"], {}, "argument --noise-sd: 0 must be a positive number"),
    ("diag-threads", [*DIAGNOSE, "--threads", "-1"], {}, "argument --threads: -1 is out of range"),
    ("diag-options-list", [*DIAGNOSE, "--options-json", "[1]"], {}, "--options-json: expected a JSON object"),
    ("diag-options-key", [*DIAGNOSE, "--options-json", '{"alpah": 0.1}'], {}, "alpah"),
    ("diag-options-json", [*DIAGNOSE, "--options-json", "{"], {}, "argument --options-json: not valid JSON"),
    ("diag-grid-key", [*DIAGNOSE, "--effect-grid-json", '{"n_speed": 4}'], {}, "n_speed"),
    (
        "diag-output-file",
        ["diagnose", "log.csv", "--table", "table.npz", "-o", "notes.txt"],
        {},
        "-o notes.txt is a file; give a folder",
    ),
    ("diag-output-log", ["diagnose", "log.csv", "--table", "table.npz", "-o", "log.csv"], {}, "-o log.csv is a file"),
    (
        "diag-output-not-empty",
        ["diagnose", "log.csv", "--table", "table.npz", "-o", "sub"],
        {},
        "-o sub is not empty; give a new folder, or --force",
    ),
    ("diag-output-here", ["diagnose", "log.csv", "--table", "table.npz", "-o", "."], {}, "-o . is not empty"),
    (
        "diag-force-foreign-file",
        ["diagnose", "log.csv", "--table", "table.npz", "-o", "sub", "--force"],
        {"sub/summary.json": "{}"},
        "sub/summary.json exists and was not written by a previous report",
    ),
    (
        "diag-force-input-inside",
        ["diagnose", "sub/residuals.csv", "--table", "table.npz", "-o", "sub", "--force"],
        {"sub/residuals.csv": PUSHLOG, "sub/.imply-manifest.json": '{"files": ["residuals.csv"]}'},
        "sub/residuals.csv is an input and would be replaced",
    ),
    (
        "diag-output-under-file",
        ["diagnose", "log.csv", "--table", "table.npz", "-o", "notes.txt/report"],
        {},
        "notes.txt is a file, not a folder",
    ),
    # -- imply table build -------------------------------------------------------------
    (
        "build-grid-order",
        [*BUILD, "--grid-json", GRID.replace('"max": 2.0', '"max": 0.1')],
        {},
        "--grid-json: masses: min 0.2 is greater than max 0.1",
    ),
    (
        "build-grid-missing",
        [*BUILD, "--grid-json", '{"speeds": {"min": 0.2, "max": 1, "n": 5}}'],
        {},
        "--grid-json: missing key 'masses'",
    ),
    (
        "build-grid-n",
        [*BUILD, "--grid-json", GRID.replace('"n": 4}', '"n": 2}', 1)],
        {},
        "--grid-json: speeds.n: 2 is less than the minimum of 4",
    ),
    (
        "build-grid-n-float",
        [*BUILD, "--grid-json", GRID.replace('"n": 4}', '"n": 4.5}', 1)],
        {},
        "4.5 is not of type 'integer'",
    ),
    (
        "build-grid-key",
        [*BUILD, "--grid-json", GRID.replace('"speeds"', '"speed"')],
        {},
        "--grid-json: unknown key 'speed' (did you mean 'speeds'?)",
    ),
    ("build-grid-list", [*BUILD, "--grid-json", "[1, 2]"], {}, "--grid-json: expected a JSON object"),
    (
        "build-grid-negative",
        [*BUILD, "--grid-json", GRID.replace('"min": 0.1, "max": 0.6', '"min": -0.1, "max": 0.6')],
        {},
        "--grid-json: frictions.min: -0.1 is less than or equal to the minimum of 0",
    ),
    ("build-timestep-zero", [*BUILD, "--scene-json", '{"timestep": 0}'], {}, "timestep must be a positive number"),
    ("build-timestep-negative", [*BUILD, "--scene-json", '{"timestep": -1}'], {}, "timestep must be a positive"),
    ("build-timestep-text", [*BUILD, "--scene-json", '{"timestep": "fast"}'], {}, "not 'fast'"),
    ("build-scene-key", [*BUILD, "--scene-json", '{"timestepp": 0.001}'], {}, "unknown key 'timestepp'"),
    ("build-scene-option", [*BUILD, "--scene-json", '{"option": {"gravty": "0 0 -9"}}'], {}, "gravty"),
    ("build-config-missing", [*BUILD, "--config", "none.yaml"], {}, "--config none.yaml: No such file"),
    ("build-config-yaml", [*BUILD, "--config", "bad.yaml"], {"bad.yaml": "scene: [1, 2\n"}, "not valid YAML"),
    (
        "build-config-scene",
        [*BUILD, "--config", "bad.yaml"],
        {"bad.yaml": "scene: {timestep: -1}\n"},
        "--config bad.yaml: scene: timestep must be a positive",
    ),
    ("build-output-folder", ["table", "build", "-o", "sub"], {}, "-o sub is a folder"),
    ("build-threads", [*BUILD, "--threads", "-2"], {}, "argument --threads: -2 is out of range"),
    ("check-table-text", ["table", "check", "notes.txt"], {}, "TABLE: notes.txt is not a push table"),
    ("check-output-is-table", ["table", "check", "table.npz", "-o", "table.npz"], {}, "-o table.npz is also an input"),
    ("check-cells", ["table", "check", "table.npz", "--cells", "0"], {}, "argument --cells: 0 is out of range"),
    # -- imply study gap diagnose-many (the workflow's batch of diagnoses) ------------------------
    (
        "many-same-stem",
        ["study", "gap", "diagnose-many", "log.csv", "sub/log.csv", "--table", "table.npz", "-o", "out"],
        {"sub/log.csv": PUSHLOG},
        "would share the report folder out/log",
    ),
    (
        "many-bad-log",
        ["study", "gap", "diagnose-many", "log.csv", "bad.csv", "--table", "table.npz", "-o", "out"],
        {"bad.csv": PUSHLOG.replace("b,0.5,0.07", "b,0.5,-1")},
        "bad.csv: row 5 (line 6), column displacement",
    ),
    (
        "many-output-file",
        ["study", "gap", "diagnose-many", "log.csv", "--table", "table.npz", "-o", "notes.txt"],
        {},
        "-o notes.txt is a file",
    ),
    # -- imply sim export-xml ------------------------------------------------------------
    ("xml-timestep-negative", [*EXPORT, "--scene-json", '{"timestep": -1}'], {}, "timestep must be a positive"),
    ("xml-timestep-zero", [*EXPORT, "--scene-json", '{"timestep": 0}'], {}, "timestep must be a positive"),
    ("xml-timestep-text", [*EXPORT, "--scene-json", '{"timestep": "fast"}'], {}, "not 'fast'"),
    ("xml-scene-list", [*EXPORT, "--scene-json", "[]"], {}, "--scene-json: expected a JSON object"),
    ("xml-scene-json", [*EXPORT, "--scene-json", "{"], {}, "argument --scene-json: not valid JSON"),
    ("xml-mass", [*EXPORT, "mass=-1"], {}, "OBJECT setting 'mass=-1': bad value"),
    ("xml-size", [*EXPORT, "size=0.1,0.1"], {}, "OBJECT setting 'size=0.1,0.1': bad value"),
    ("xml-setting", [*EXPORT, "colour=red"], {}, "unknown OBJECT setting 'colour'"),
    ("xml-not-key-value", [*EXPORT, "heavy"], {}, "OBJECT setting 'heavy' is not key=value"),
    ("xml-output-folder", ["sim", "export-xml", "-o", "sub"], {}, "-o sub is a folder"),
    # -- imply sim pushes --------------------------------------------------------------
    ("push-missing-file", ["sim", "pushes", "none.csv", "-o", "o.csv"], {}, "none.csv: no such file"),
    ("push-speed", PUSH, {"pushes.csv": "object_id,speed\nx,fast\n"}, "row 1 (line 2), column speed"),
    ("push-mass", PUSH, {"pushes.csv": "object_id,speed,mass\nx,0.5,-1\n"}, "row 1 (line 2), column mass"),
    ("push-output-is-input", ["sim", "pushes", "pushes.csv", "-o", "pushes.csv"], {}, "is also an input"),
    ("push-no-model", [*PUSH, "--model", "none.xml"], {}, "--model none.xml: no such file"),
    ("push-bad-model", [*PUSH, "--model", "notes.txt"], {}, "--model notes.txt:"),
    ("push-model-timestep", [*PUSH, "--model", "m.xml"], {"m.xml": "zero-timestep"}, "timestep 0 must be positive"),
    ("push-timestep", [*PUSH, "--scene-json", '{"timestep": -1}'], {}, "timestep must be a positive"),
]


@pytest.fixture
def workdir(tmp_path, tiny_table_path, monkeypatch) -> Path:
    """A folder of good inputs, a bystander file and a non-empty subfolder; the cwd of each case."""
    shutil.copy(tiny_table_path, tmp_path / "table.npz")
    (tmp_path / "r.csv").write_text(ROLLOUTS)
    (tmp_path / "log.csv").write_text(PUSHLOG)
    (tmp_path / "pushes.csv").write_text(PUSHES)
    (tmp_path / "notes.txt").write_text("my notes\n")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "notes.txt").write_text("more notes\n")
    monkeypatch.chdir(tmp_path)
    return tmp_path


def _special(path: Path, kind: str) -> None:
    if kind == "nan-speed":
        pd.DataFrame(
            {"object_id": ["a", "a"], "role": ["rollout"] * 2, "speed": [0.3, np.nan], "displacement": [0.02, 0.04]}
        ).to_parquet(path)
    elif kind == "negative-speed":
        frame = pd.read_csv(pd.io.common.StringIO(PUSHLOG))
        frame.loc[3, "speed"] = -1.0
        frame.to_parquet(path)
    elif kind == "npz":
        np.savez(path, something=np.zeros(3))
    elif kind == "zero-timestep":
        import re

        from imply.sim import build_xml

        path.write_text(re.sub(r'timestep="[^"]*"', 'timestep="0"', build_xml()))
    else:
        raise ValueError(kind)


def _snapshot(folder: Path) -> dict[str, str]:
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest() if p.is_file() else "dir"
        for p in sorted(folder.rglob("*"))
    }


@pytest.mark.parametrize("argv, files, expected", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_refused_in_one_line_with_exit_2_and_nothing_written(workdir, capsys, argv, files, expected):
    for name, content in files.items():
        path = workdir / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(content, bytes):
            path.write_bytes(content)
        elif content in ("nan-speed", "negative-speed", "npz", "zero-timestep"):
            _special(path, content)
        else:
            path.write_text(content)
    before = _snapshot(workdir)
    try:
        code = main(list(argv))
    except SystemExit as exc:  # argparse refusals
        code = exc.code
    err = capsys.readouterr().err.strip()
    lines = [ln for ln in err.splitlines() if " INFO " not in ln]
    assert code == 2, err
    assert len(lines) == 1, err
    assert lines[0].startswith("imply ") and ": error: " in lines[0], lines[0]
    assert expected in lines[0], lines[0]
    assert _snapshot(workdir) == before


def test_case_ids_are_unique():
    ids = [c[0] for c in CASES]
    assert len(ids) == len(set(ids))


@pytest.mark.parametrize(
    "argv",
    [
        ["score", "r.csv", "--table", "table.npz", "-o", "r.csv"],
        ["score", "r.csv", "--table", "table.npz", "-o", "s.csv", "--grid", "100000"],
        ["sim", "export-xml", "--scene-json", '{"timestep": -1}', "-o", "box.xml"],
        ["diagnose", "log.csv", "--table", "table.npz", "-o", "."],
    ],
    ids=["output-is-input", "grid", "timestep", "diagnose-here"],
)
def test_console_script_exits_2_with_one_line(workdir, argv):
    """The installed entry point, as a user runs it: no traceback, exit status 2."""
    before = _snapshot(workdir)
    proc = subprocess.run([sys.executable, "-m", "imply.cli", *argv], capture_output=True, text=True, cwd=workdir)
    assert proc.returncode == 2, proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert "Traceback" not in proc.stderr
    assert _snapshot(workdir) == before
