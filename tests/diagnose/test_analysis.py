"""`imply diagnose` end to end on a tiny table: an oblique tilt, two effects at once, the null, outliers.

The push logs come from the benchmark's world (:mod:`imply.realworld`: its own stepping and
effect mechanisms, no tables), never from the diagnostic's effect tables.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from imply.cli import main
from imply.io import write_csv
from imply.realworld import cases as C
from imply.sim import SceneConfig
from sample_inputs import EFFECT_GRID_JSON, PUSHLOG_CSV

EFFECTS = "tilt,speed_offset,viscous"
DESIGN = C.BenchmarkConfig.from_dict(
    {"seed": 0, "n_objects": 8, "speeds": [0.25, 0.45, 0.65, 0.85], "masses": [0.3, 1.5], "frictions": [0.15, 0.45]}
)


@pytest.fixture(scope="module")
def cache(effect_cache):
    return effect_cache


def _case(effects: list[dict], seed: int, *, stop_time: bool = False, measured_mass: bool = True, noise="gaussian"):
    rng = np.random.default_rng(seed)
    n = DESIGN.n_objects
    return {
        "id": f"case{seed}",
        "group": "test",
        "effects": effects,
        "mass": np.exp(rng.uniform(*np.log(DESIGN.masses), n)).tolist(),
        "friction": np.exp(rng.uniform(*np.log(DESIGN.frictions), n)).tolist(),
        "direction": rng.uniform(0, 2 * np.pi, n * len(DESIGN.speeds)).tolist(),
        "measured_mass": measured_mass,
        "stop_time": stop_time,
        "noise": noise,
        "noise_seed": seed,
    }


def _effect(name: str, magnitude: float, azimuth_deg: float | None = None) -> dict:
    return {
        "name": name,
        "magnitude": magnitude,
        "in_library": True,
        "azimuth": None if azimuth_deg is None else float(np.radians(azimuth_deg)),
    }


def _diagnose(
    tmp_path, tiny_table, tiny_table_path, cache, case: dict, extra=(), track=False
) -> tuple[dict, dict, str]:
    scene = SceneConfig.from_dict(tiny_table.meta["scene"])
    sims = C.simulate_cases([case], DESIGN, scene, nthread=2)
    frame, label = C.make_log(case, sims[case["id"]], DESIGN, scene)
    log = tmp_path / f"{case['id']}.csv"
    write_csv(log, frame)
    if track:  # beside the log, where `imply diagnose` finds it
        write_csv(tmp_path / f"{case['id']}.track.csv", C.log_track(case, sims[case["id"]], label, DESIGN))
    out = tmp_path / f"report-{case['id']}"
    argv = [
        "diagnose",
        str(log),
        "--table",
        str(tiny_table_path),
        "--effects",
        EFFECTS,
        "--effect-grid-json",
        EFFECT_GRID_JSON,
        "--cache-dir",
        str(cache),
        "--threads",
        "2",
        "-o",
        str(out),
        *extra,
    ]
    assert main(argv) == 0
    for name in (
        "summary.json",
        "report.md",
        "residuals.csv",
        "next_pushes.csv",
        "residuals_vs_speed.png",
        "before_after.png",
        "ranking.png",
        "hypotheses.png",
    ):
        assert (out / name).is_file(), name
    with open(out / "summary.json") as fh:
        return json.load(fh), label, (out / "report.md").read_text()


def test_oblique_tilt_is_one_effect_with_its_azimuth(tmp_path, tiny_table, tiny_table_path, cache):
    """A table sloping toward 35 degrees (not along an axis) is found as one tilt, with its direction."""
    # inside the library's range: a tilt at its largest magnitude (0.03) lands on the bound half the time, and an
    # effect on its bound is never stated
    case = _case([_effect("tilt", 0.025, 35.0)], seed=11, stop_time=True)
    s, label, report = _diagnose(tmp_path, tiny_table, tiny_table_path, cache, case)
    assert s["verdict"]["effects"] == ["tilt"], s["verdict"]
    tilt = s["effects"][0]
    assert abs(tilt["magnitude"] - 0.025) < 0.008
    assert abs(((tilt["azimuth_deg"] - 35.0) + 180) % 360 - 180) < 20
    lo, hi = tilt["azimuth_ci95_deg"]
    assert lo < tilt["azimuth_deg"] < hi
    assert s["observables"] == ["displacement", "stop_time"]
    # the report leads with the verdict in one sentence, then the evidence
    first = report.split("\n")[2]
    assert first.startswith("**The gap is explained (the leading hypothesis closes ")
    assert ", and by one cause: the table slopes" in first and "toward" in first
    assert "Observables used: displacement and stop time" in report
    assert s["shrinkage"]["gap_share_closed"] > 0.6


def test_two_effects_at_once_are_both_named(tmp_path, tiny_table, tiny_table_path, cache):
    case = _case([_effect("tilt", 0.025, 200.0), _effect("speed_offset", 0.05)], seed=12)
    s, label, report = _diagnose(tmp_path, tiny_table, tiny_table_path, cache, case)
    assert sorted(s["verdict"]["effects"]) == ["speed_offset", "tilt"], s["verdict"]
    by = {e["effect"]: e for e in s["effects"]}
    assert abs(by["speed_offset"]["magnitude"] - 0.05) < 0.015
    assert abs(((by["tilt"]["azimuth_deg"] - 200.0) + 180) % 360 - 180) < 25
    assert s["verdict"]["identification"] == "one_cause"
    lead = s["hypotheses"][0]
    assert sorted(lead["effects"]) == ["speed_offset", "tilt"] and lead["weight"] > 0.5
    assert s["inclusion"]["tilt"] > 0.95 and s["inclusion"]["speed_offset"] > 0.95
    assert "the table slopes" in report and "than commanded" in report


def test_null_log_with_gross_outliers_raises_no_alarm(tmp_path, tiny_table, tiny_table_path, cache):
    """Heavy-tailed noise and gross outliers: the outliers are flagged and left out, and the verdict is none."""
    case = _case([], seed=13, noise="heavy")
    s, label, report = _diagnose(tmp_path, tiny_table, tiny_table_path, cache, case)
    assert s["verdict"]["effects"] == [] and s["verdict"]["adequacy"] == "no_gap", s["verdict"]
    flagged = {tuple(label["rows_kept"][r["row"]]) for r in s["outliers"]["displacement"]}
    true = {(p, r) for r, p in label["outliers"]}
    assert true <= flagged
    assert "Gross outliers" in report
    assert s["noise"]["source"] == "replicate pushes"


def test_speed_gain_is_reported_as_aliased_with_friction(tmp_path, tiny_table, tiny_table_path, cache):
    """With weighed masses, a commanded-speed gain looks like a friction change: the report says so."""
    case = _case([], seed=14)
    s, _, _ = _diagnose(tmp_path, tiny_table, tiny_table_path, cache, case, extra=["--effects", "speed_gain,tilt"])
    alias = s["aliasing"]["effects"]["speed_gain"]
    assert alias["absorbed_by_fit"] > 0.5 and "friction change" in alias["fit_alias"], alias
    assert "unless friction is measured" in alias["fit_alias"]


PUSHLOG = PUSHLOG_CSV


def test_report_folder_is_fresh_and_force_keeps_other_files(tmp_path, tiny_table_path, cache, monkeypatch, capsys):
    """The user's files survive: a non-empty folder is refused, and --force replaces only the report."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "log.csv").write_text(PUSHLOG)
    (tmp_path / "notes.txt").write_text("my notes\n")
    args = [
        "diagnose",
        "log.csv",
        "--table",
        str(tiny_table_path),
        "--effects",
        "speed_gain",
        "--effect-grid-json",
        EFFECT_GRID_JSON,
        "--cache-dir",
        str(cache),
        "--noise-sd",
        "0.05",
    ]
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
        [
            ".imply-manifest.json",
            "summary.json",
            "report.md",
            "residuals.csv",
            "next_pushes.csv",
            "next_probes.csv",
            "residuals_vs_speed.png",
            "before_after.png",
            "ranking.png",
            "hypotheses.png",
        ]
    )
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".report")]  # no temporary folder left


def test_ranking_colours_mark_only_the_verdict_green():
    from imply.diagnose.inference.estimates import RankedCandidate
    from imply.diagnose.report import ranking_colours

    def row(effect: str, identifiable: bool, improvement: float) -> RankedCandidate:
        return RankedCandidate(
            effect=effect,
            title="",
            unit="",
            components={},
            magnitude=0.0,
            ci95=(0.0, 0.0),
            sd=0.0,
            at_bound=False,
            cls=effect,
            identifiable=identifiable,
            lr_stat=0.0,
            df=1,
            lr_critical=1.0,
            heldout_gain=0.0,
            heldout_improvement=improvement,
            explained_ms=0.0,
            floor_ms=0.0,
            qualifies=False,
            reasons=[],
            delta_bic=0.0,
        )

    ranking = [
        row("tilt", True, 0.6),
        row("viscous", True, 0.1),
        row("height", False, 0.05),
        row("speed_gain", True, -4.0),
    ]
    assert ranking_colours(ranking, ["tilt"]) == ["C2", "C0", "0.75", "C3"]
    assert "C2" not in ranking_colours(ranking, [])  # "none of the candidates": nothing is green


def test_the_pushers_measured_speed_joins_every_fit_and_narrows_a_speed_error(
    tmp_path, tiny_table, tiny_table_path, cache
):
    """A commanded speed 0.05 m/s off, masses weighed: with the pusher's measured speed in every hypothesis's fit
    the offset is found as before, within a narrower interval, and the report says what each observable told apart;
    without it, the report says what measuring it would add."""
    case = _case([_effect("speed_offset", 0.05)], seed=21)
    on = ["--options-json", '{"use_pusher_speed": true}']
    s, _, report = _diagnose(tmp_path, tiny_table, tiny_table_path, cache, case, extra=on)
    s0, _, report0 = _diagnose(tmp_path / "off", tiny_table, tiny_table_path, cache, case)
    assert s["observables"] == ["displacement", "pusher_speed"] and s0["observables"] == ["displacement"]
    assert "the pusher's measured speed" in s["observables_note"] and "not used" in s0["observables_note"]
    assert s["noise"]["pusher_speed_sd"] < 0.02  # the encoders' noise (0.01), estimated from the replicates
    by, by0 = ({e["effect"]: e for e in x["effects"]} for x in (s, s0))
    assert abs(by["speed_offset"]["magnitude"] - 0.05) < 0.01
    width = by["speed_offset"]["ci95"][1] - by["speed_offset"]["ci95"][0]
    width0 = by0["speed_offset"]["ci95"][1] - by0["speed_offset"]["ci95"][0]
    assert width < 0.8 * width0, (width, width0)
    residuals = (tmp_path / f"report-{case['id']}" / "residuals.csv").read_text().splitlines()[0]
    assert "pusher_speed_resid_before" in residuals


def test_the_boxs_track_joins_every_fit_and_narrows_a_viscous_drag(tmp_path, tiny_table, tiny_table_path, cache):
    """Viscous friction, masses weighed, the box filmed at 60 frames a second: with the track beside the log, every
    hypothesis's fit explains the times the box takes to cover fractions of its travel too, their noise is estimated
    from the replicates, and the drag is found within a narrower interval;
    with ``use_track`` off, the report says the log's track was not used."""
    case = _case([_effect("viscous", 0.6)], seed=23, stop_time=True)
    on = ["--options-json", '{"use_track": true}']
    s, _, _ = _diagnose(tmp_path, tiny_table, tiny_table_path, cache, case, extra=on, track=True)
    off = ["--options-json", '{"use_track": false}']
    s0, _, _ = _diagnose(tmp_path / "off", tiny_table, tiny_table_path, cache, case, extra=off, track=True)
    assert s["observables"] == ["displacement", "stop_time", "crossing_25", "crossing_50", "crossing_75"]
    assert s0["observables"] == ["displacement", "stop_time"] and "track" in s0["observables_note"]
    # 1 mm of camera noise on travels of a few cm at 60 frames a second: several percent of a crossing time
    assert 0.01 < s["noise"]["aux_sd"]["crossing_50"] < 0.15, s["noise"]
    by, by0 = ({e["effect"]: e for e in x["effects"]} for x in (s, s0))
    width = by["viscous"]["ci95"][1] - by["viscous"]["ci95"][0]
    width0 = by0["viscous"]["ci95"][1] - by0["viscous"]["ci95"][0]
    assert width < width0, (width, width0)
