"""`imply diagnose LOG --reference REF` end to end on a tiny table: a robot whose contact is not the table's.

The logs come from the benchmark's world (:mod:`imply.realworld`), whose contact model is
drawn apart from the table's: the standing gap. The log adds an effect; its reference session
is the same world and boxes without it, one push of each, with noise of its own
(:func:`imply.realworld.cases.reference_log`).
"""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from imply.cli import main
from imply.diagnose.inference.fit import Problem
from imply.diagnose.inference.sessions import against_reference
from imply.diagnose.inputs.probes import Probes
from imply.diagnose.inputs.pushlog import PushLog
from imply.diagnose.physics.candidates import Model
from imply.diagnose.physics.probe_fit import Servo
from imply.io import write_csv
from imply.realworld import cases as C
from imply.sim import SceneConfig
from sample_inputs import EFFECT_GRID_JSON, PUSHLOG_CSV

EFFECTS = "tilt,speed_offset,viscous"
DESIGN = C.ContactBenchmarkConfig.from_dict(
    {"seed": 0, "n_objects": 8, "speeds": [0.25, 0.45, 0.65, 0.85], "masses": [0.3, 1.5], "frictions": [0.15, 0.45]}
)


@pytest.fixture(scope="module")
def cache(effect_cache):
    return effect_cache


def _case(effects: list[dict], seed: int) -> dict:
    rng = np.random.default_rng(seed)
    n = DESIGN.n_objects
    return {
        "id": f"case{seed}",
        "group": "test",
        "effects": effects,
        "mass": np.exp(rng.uniform(*np.log(DESIGN.masses), n)).tolist(),
        "friction": np.exp(rng.uniform(*np.log(DESIGN.frictions), n)).tolist(),
        "direction": rng.uniform(0, 2 * np.pi, n * len(DESIGN.speeds)).tolist(),
        "measured_mass": True,
        "stop_time": True,
        "noise": "gaussian",
        "noise_seed": seed,
        "engine": "mujoco",
        # the robot's standing gap: friction that changes with speed, and a pusher contact of its own
        "contact": {
            "kinds": ["pusher_contact", "speed_friction"],
            "parameters": {
                "friction_slope": 0.7,
                "friction_slope_speed": 0.15,
                "pusher_impedance": 0.3,
                "pusher_friction": 0.5,
            },
        },
        "design": "random",
    }


@pytest.fixture(scope="module")
def sessions(tiny_table, tmp_path_factory):
    """A tilted-table log of a robot with a standing gap, its reference session, and a null log of the same robot."""
    scene = SceneConfig.from_dict(tiny_table.meta["scene"])
    tilt = {"name": "tilt", "magnitude": 0.025, "in_library": True, "azimuth": float(np.radians(60.0))}
    effect, null = _case([tilt], seed=21), _case([], seed=22)
    sims = C.simulate_cases([effect, null], DESIGN, scene, nthread=2)
    folder = tmp_path_factory.mktemp("sessions")
    for case in (effect, null):
        frame, _ = C.make_log(case, sims[case["id"]], DESIGN, scene)
        write_csv(folder / f"{case['id']}.csv", frame)
        write_csv(folder / f"{case['id']}-before.csv", C.reference_log(case, sims[case["id"]], DESIGN, scene))
    return folder


def _diagnose(tiny_table_path, cache, log, out, *extra) -> tuple[dict, str]:
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
        "--no-plots",
        "-o",
        str(out),
        *extra,
    ]
    assert main(argv) == 0
    return json.loads((out / "summary.json").read_text()), (out / "report.md").read_text()


def test_reference_session_tells_the_change_from_the_standing_gap(tiny_table_path, cache, sessions, tmp_path):
    """Against its reference, the tilt is the one change, near its size, and the report gives both gaps; the same
    robot with nothing changed states no change, though its standing gap is there (one test: one effect cache)."""
    s, report = _diagnose(
        tiny_table_path,
        cache,
        sessions / "case21.csv",
        tmp_path / "r",
        "--reference",
        str(sessions / "case21-before.csv"),
    )
    v = s["verdict"]
    assert v["effects"] == ["tilt"] and v["identification"] == "one_cause", s["sentence"]
    tilt = next(e for e in s["effects"] if e["effect"] == "tilt")
    assert abs(tilt["magnitude"] - 0.025) < 0.3 * 0.025
    ref = s["reference"]
    assert ref["objects_shared"] == C.object_names(8) and ref["objects_log_only"] == []
    assert ref["pushes_matched"] == s["n_pushes"] and ref["pushes_modelled"] == 0
    # the standing gap is the reference's own gap: well beyond its noise
    assert ref["standing"]["adequacy"] != "no_gap" and ref["standing"]["baseline_rms"] > 3 * ref["standing"]["noise_sd"]
    shrink = s["cause_shrink"]
    assert shrink["cause_and_standing_share_closed"] > 0.8
    assert (
        s["sentence"].startswith("The standing gap, read from the reference session")
        and " Since the reference, the gap is " in s["sentence"]
    )
    assert "## Against a reference session" in report and "**The standing gap**" in report

    s, _ = _diagnose(
        tiny_table_path,
        cache,
        sessions / "case22.csv",
        tmp_path / "n",
        "--reference",
        str(sessions / "case22-before.csv"),
    )
    assert s["verdict"]["effects"] == [], s["sentence"]
    assert s["reference"]["standing"]["adequacy"] != "no_gap"
    assert " Since the reference, nothing beyond noise changed" in s["sentence"]


def test_reference_without_shared_boxes_is_refused_in_one_line(tiny_table_path, tmp_path, capsys):
    log, other = tmp_path / "log.csv", tmp_path / "other.csv"
    log.write_text(PUSHLOG_CSV)
    frame = pd.read_csv(log)
    frame["object_id"] = "crate-" + frame["object_id"].astype(str)
    frame.to_csv(other, index=False)
    argv = ["diagnose", str(log), "--table", str(tiny_table_path), "--reference", str(other)]
    assert main([*argv, "-o", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "pushes none of the boxes" in err[0], err
    assert not (tmp_path / "x").exists()


def _log(table, boxes: dict[str, tuple[float, float]], speeds, shift: float, path: str) -> PushLog:
    """A push log of ``boxes`` ({name: (mass, friction)}) at ``speeds``, the table's slides shifted by ``shift`` in
    log d (a standing gap of the simplest kind), the masses measured."""
    names = list(boxes)
    obj = np.repeat(np.arange(len(names)), len(speeds))
    v = np.tile(np.asarray(speeds, float), len(names))
    m = np.array([boxes[n][0] for n in names])[obj]
    mu = np.array([boxes[n][1] for n in names])[obj]
    return PushLog(
        path=path,
        frame=pd.DataFrame({"object_id": [names[i] for i in obj], "speed": v}),
        objects=names,
        obj=obj,
        speed=v,
        displacement=np.exp(table.log_displacement(v, m, mu) + shift),
        direction=np.zeros(v.size),
        has_direction=False,
        mass=np.array([boxes[n][0] for n in names]),
    )


def test_the_standing_gap_comes_out_by_the_reference_s_own_pushes_where_it_ran_them(tiny_table):
    """Boxes of one session only, pushes the reference never ran: what each is paired with, and the new session's
    change alone left where the reference ran the same push."""
    boxes = {"a": (0.4, 0.2), "b": (0.8, 0.3), "c": (1.2, 0.25), "d": (0.5, 0.4)}
    new = _log(tiny_table, {k: boxes[k] for k in "abc"}, [0.3, 0.5, 0.7, 0.9], 0.15, "new.csv")
    ref = _log(tiny_table, {k: boxes[k] for k in "bcd"}, [0.3, 0.5, 0.7], 0.10, "ref.csv")
    ref_problem = Problem.of(ref, tiny_table, None, grid=31).with_noise(0.02, None)
    standing = ref_problem.fit(Model(), np.zeros(0), ref_problem.initial_fit())
    corrected, pairing = against_reference(new, ref_problem, standing, observables_used=())
    assert (pairing.objects_shared, pairing.objects_log_only, pairing.objects_reference_only) == (
        ["b", "c"],
        ["a"],
        ["d"],
    )
    assert corrected.objects == ["b", "c"] and corrected.n == 8
    assert (pairing.pushes_matched, pairing.pushes_modelled) == (6, 2)
    # where the reference ran the push: the new reading less the reference's, on the table at the reference's fit
    problem = Problem.of(corrected, tiny_table, None, grid=31)
    at = np.array([ref.objects.index(o) for o in corrected.objects])[problem.c_obj]
    table_hat = problem.predict(Model(), np.zeros(0), standing.objects.lm[at], standing.objects.lu[at]).log_d
    matched = corrected.speed < 0.8
    np.testing.assert_allclose((corrected.log_d - table_hat[problem.cond])[matched], 0.05, atol=1e-9)
    # the reference's noise is counted there (one push of each: its whole sd), and nowhere else
    np.testing.assert_allclose(corrected.baseline_sd["displacement"], np.where(matched, 0.02, 0.0))


def _probes(path: str, strokes: dict[float, float], friction: list[float], sd: list[float]) -> Probes:
    """Probes of free strokes ({commanded speed: measured mean speed}) and friction measurements (NaN: none), and one
    loaded push of the first box."""
    one = np.ones(1)
    return Probes(
        path=path,
        free_stroke_speed=np.array(list(strokes), float),
        free_stroke_pusher_speed=np.array(list(strokes.values()), float),
        friction=np.array(friction, float),
        friction_sd=np.array(sd, float),
        friction_speed=np.full(len(friction), np.nan),
        friction_direction=np.full(len(friction), np.nan),
        added_obj=np.zeros(1, int),
        added_speed=0.5 * one,
        added_displacement=0.05 * one,
        added_mass=0.2 * one,
        added_direction=np.full(1, np.nan),
        added_stop_time=np.full(1, np.nan),
        added_pusher_speed=np.full(1, np.nan),
    )


def test_the_probes_lose_the_standing_gap_by_the_reference_s_probes_of_the_same_kind(tiny_table):
    """A free stroke over the reference's at the same speed, a friction reading over the reference's of the same box;
    what the reference did not run, and the loaded pushes, are left out and said."""
    boxes = {"b": (0.8, 0.3), "c": (1.2, 0.25)}
    new = _log(tiny_table, boxes, [0.3, 0.5, 0.7], 0.15, "new.csv")
    ref = _log(tiny_table, boxes, [0.3, 0.5, 0.7], 0.10, "ref.csv")
    new = replace(new, probes=_probes("new.probes.csv", {0.3: 0.27, 0.6: 0.50, 0.9: 0.80}, [0.33, 0.2], [0.02, 0.02]))
    ref = replace(ref, probes=_probes("ref.probes.csv", {0.3: 0.25, 0.6: 0.52}, [0.30, np.nan], [0.03, np.nan]))
    ref_problem = Problem.of(ref, tiny_table, None, grid=31).with_noise(0.02, None)
    standing = ref_problem.fit(Model(), np.zeros(0), ref_problem.initial_fit())
    corrected, pairing = against_reference(new, ref_problem, standing, observables_used=())
    p = corrected.probes
    servo = Servo.of_scene(tiny_table.meta["scene"])
    np.testing.assert_allclose(p.free_stroke_speed, [0.3, 0.6])
    np.testing.assert_allclose(
        p.free_stroke_pusher_speed, [0.27, 0.50] * servo.mean_speed(np.array([0.3, 0.6])) / [0.25, 0.52]
    )
    np.testing.assert_allclose(p.friction[0], 0.33 / 0.30 * np.exp(standing.objects.lu[0]))
    np.testing.assert_allclose(p.friction_sd[0] / p.friction[0], np.hypot(0.02 / 0.33, 0.03 / 0.30))
    assert np.isnan(p.friction[1]) and p.n_added == 0
    assert pairing.observables_dropped == [
        "1 free stroke(s) at speeds the reference did not stroke",
        "1 friction measurement(s) of boxes the reference did not measure",
        "1 loaded push(es)",
    ]
