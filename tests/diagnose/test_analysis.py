"""`imply diagnose` end to end on a tiny table: an injected effect is found, the null is not flagged.

The push logs come from the benchmark's generator (its own scene timestep, direct
simulation, noise), never from the diagnostic's effect tables.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from imply.cli import main
from imply.diagnose.benchmark import BenchmarkConfig, simulate_case
from imply.io import write_csv
from imply.sim import SceneConfig
from sample_inputs import PUSHLOG_CSV

EFFECTS = "tilt_x,speed_gain,viscous"
GRID = '{"n_speeds": 4, "n_masses": 4, "n_frictions": 4}'
DESIGN = BenchmarkConfig(n_objects=10, noise_sd=0.02, timestep=0.0009)


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return tmp_path_factory.mktemp("effect-cache")


def _diagnose(tmp_path, tiny_table, tiny_table_path, cache, effect: str, magnitude: float, seed: int) -> dict:
    case = {"id": effect, "effect": effect, "magnitude": magnitude, "seed": seed}
    frame, label = simulate_case(case, SceneConfig.from_dict(tiny_table.meta["scene"]), DESIGN, nthread=2)
    assert "effect" not in frame.columns and label["effect"] == effect
    log = tmp_path / f"{effect}.csv"
    write_csv(log, frame)
    out = tmp_path / f"report-{effect}"
    argv = ["diagnose", str(log), "--table", str(tiny_table_path), "--effects", EFFECTS,
            "--effect-grid-json", GRID, "--cache-dir", str(cache), "--threads", "2", "-o", str(out)]  # fmt: skip
    assert main(argv) == 0
    for name in (
        "summary.json",
        "report.md",
        "residuals.csv",
        "residuals_vs_speed.png",
        "before_after.png",
        "ranking.png",
    ):
        assert (out / name).is_file(), name
    with open(out / "summary.json") as fh:
        return json.load(fh)


def test_injected_tilt_is_identified(tmp_path, tiny_table, tiny_table_path, cache):
    s = _diagnose(tmp_path, tiny_table, tiny_table_path, cache, "tilt_x", 0.03, seed=11)
    assert s["verdict"]["effect"] == "tilt_x"
    top = next(r for r in s["ranking"] if r["effect"] == "tilt_x")
    lo, hi = top["ci95"]
    assert lo <= top["magnitude"] <= hi
    assert abs(top["magnitude"] - 0.03) < 0.01
    # direction is where the gap lies: pushes along +x and -x differ from zero, in opposite senses
    bands = {b["band"]: b for b in s["localisation"]["direction"]}
    assert bands["0 deg"]["differs"] and bands["180 deg"]["differs"]
    assert bands["0 deg"]["mean"] * bands["180 deg"]["mean"] < 0
    sh = s["shrinkage"]
    assert sh["after_rms"] < 0.5 * sh["before_rms"] and sh["gap_share_closed"] > 0.5
    assert s["noise"]["source"] == "replicate pushes" and abs(s["noise"]["sd"] - 0.02) < 0.005


def test_null_log_raises_no_alarm(tmp_path, tiny_table, tiny_table_path, cache):
    s = _diagnose(tmp_path, tiny_table, tiny_table_path, cache, "null", 0.0, seed=12)
    assert s["verdict"]["verdict"] == "none"
    assert s["shrinkage"]["unexplained_rms_above_floor"] < 0.02
    assert np.isfinite(s["baseline"]["rms"])


PUSHLOG = PUSHLOG_CSV


def test_report_folder_is_fresh_and_force_keeps_other_files(tmp_path, tiny_table_path, cache, monkeypatch, capsys):
    """The user's files survive: a non-empty folder is refused, and --force replaces only the report."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "log.csv").write_text(PUSHLOG)
    (tmp_path / "notes.txt").write_text("my notes\n")
    args = ["diagnose", "log.csv", "--table", str(tiny_table_path), "--effects", "speed_gain", "--effect-grid-json",
            GRID, "--cache-dir", str(cache), "--noise-sd", "0.05"]  # fmt: skip
    assert main([*args, "-o", "."]) == 2
    assert "-o . is not empty" in capsys.readouterr().err
    assert main([*args, "-o", ".", "--force"]) == 0
    assert (tmp_path / "notes.txt").read_text() == "my notes\n"
    assert (tmp_path / "log.csv").read_text() == PUSHLOG
    assert (tmp_path / "summary.json").is_file() and (tmp_path / ".imply-manifest.json").is_file()

    report = tmp_path / "report"
    assert main([*args, "-o", str(report)]) == 0
    (report / "my_reading.md").write_text("keep me")
    assert main([*args, "-o", str(report)]) == 2
    assert main([*args, "-o", str(report), "--force"]) == 0
    assert (report / "my_reading.md").read_text() == "keep me"
    assert sorted(p.name for p in report.iterdir() if p.name != "my_reading.md") == sorted(
        [".imply-manifest.json", "summary.json", "report.md", "residuals.csv", "residuals_vs_speed.png",
         "before_after.png", "ranking.png"]
    )  # fmt: skip
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".report")]  # no temporary folder left


def test_ranking_colours_mark_only_the_verdict_green():
    from imply.diagnose.report import ranking_colours

    summary = {
        "verdict": {"effect": "tilt_x"},
        "ranking": [
            {"effect": "tilt_x", "identifiable": True, "heldout_improvement": 0.6},
            {"effect": "viscous", "identifiable": True, "heldout_improvement": 0.1},
            {"effect": "height", "identifiable": False, "heldout_improvement": 0.05},
            {"effect": "speed_gain", "identifiable": True, "heldout_improvement": -4.0},
        ],
    }
    assert ranking_colours(summary) == ["C2", "C0", "0.75", "C3"]
    summary["verdict"]["effect"] = None  # "none of the candidates": nothing is green
    assert "C2" not in ranking_colours(summary)
