"""The stated causes put into the simulator (imply.diagnose.conclusion.simulator_check): corrected.xml, the shrink
re-simulated and refitted, and the causes withdrawn where the simulator or the probes contradict them.

The tilted log comes from the benchmark's world (imply.realworld: its own stepping and effect mechanisms), never
from the effect tables the verdict reads."""

from __future__ import annotations

import json
from dataclasses import replace

import mujoco
import numpy as np
import pandas as pd
import pytest
from test_analysis import _case, _diagnose, _effect
from test_probe_fit import SCENE, probes_of
from test_steps import OPTS, make_log

from imply.cli import main
from imply.diagnose.analysis import Summary
from imply.diagnose.conclusion.render import verdict_text
from imply.diagnose.conclusion.simulator_check import PushSet, Scene, compare_shares, probe_kinds, simulate_log
from imply.diagnose.conclusion.verdict import Identification, contradicted
from imply.diagnose.inference.fit import Problem
from imply.diagnose.physics import candidates
from imply.diagnose.physics.candidates import Model
from imply.diagnose.physics.probe_fit import Servo
from imply.sim.scene import SceneConfig, build_xml
from run_folders import built_once

TRUE_TILT = 0.02


@pytest.fixture(scope="module")
def cache(effect_cache):
    return effect_cache


@pytest.fixture(scope="module")
def tilted(tmp_path_factory, tiny_table, tiny_table_path, cache):
    """A table sloping 0.02 rad toward the table's +x, diagnosed with the simulator refit: (summary, report folder)."""
    # slides alone (the tutorial's test refits stop times too): a refit of stop times records every push each ms
    case = _case([_effect("tilt", TRUE_TILT, 0.0)], seed=21)
    # one iteration: the refit starts at the tables' estimate, and an iteration is several passes over the log
    extra = ["--refit", "--options-json", '{"refit_iterations": 1}']
    # diagnosed by one test worker for all of this module's tests, whichever workers run them
    tmp = built_once(
        tmp_path_factory,
        "tilted",
        lambda folder: _diagnose(folder, tiny_table, tiny_table_path, cache, case, extra=extra),
    )
    folder = tmp / f"report-{case['id']}"
    return json.loads((folder / "summary.json").read_text()), folder


@pytest.mark.slow
def test_the_corrected_scene_holds_the_stated_tilt_and_loads_plainly(tilted):
    s, folder = tilted
    assert s["verdict"]["effects"] == ["tilt"], s["verdict"]
    model = mujoco.MjModel.from_xml_path(str(folder / "corrected.xml"))
    g = model.opt.gravity
    slope = float(np.arctan2(np.hypot(g[0], g[1]), -g[2]))
    assert abs(slope - TRUE_TILT) < 0.008
    # downhill where the verdict says (table frame: the corrected scene is the frame of a push in direction 0)
    assert abs(((np.degrees(np.arctan2(g[1], g[0])) - s["effects"][0]["azimuth_deg"]) + 180) % 360 - 180) < 1.0
    for kind, name in (("body", "box"), ("geom", "pusher"), ("joint", "push"), ("actuator", "servo")):
        getattr(model, kind)(name)
    report = (folder / "report.md").read_text()
    assert "## The causes in the simulator" in report and "re-simulated" in report


def test_the_shrink_is_re_simulated_beside_the_predicted_one(tilted):
    s, _ = tilted
    c = s["simulator"]
    assert c["n_pushes"] == s["n_pushes"] and c["n_failed"] == 0
    # the simulator, with the cause added, closes most of the gap, as the tables predict
    assert c["share_closed"] > 0.6 and c["predicted_share_closed"] > 0.6
    assert c["after_rms"] < c["before_rms"] and c["gap_left_sd"] < 1.5
    assert not c["simulator_contradicts"] and s["verdict"]["identification"] == "one_cause"
    assert c["gap_left_sd"] == pytest.approx(c["after_rms"] / c["noise_sd"])


def test_the_refit_in_the_simulator_brackets_the_true_slope(tilted):
    """The refit (mujoco.sysid.optimize, from the tables' estimate) and its interval, on the world's true slope."""
    r = tilted[0]["simulator"]["refit"]
    tx, ty = r["simulator"]["tilt"]
    assert abs(np.hypot(tx, ty) - TRUE_TILT) < 0.006
    (lo, hi), _ = r["simulator_ci95"]["tilt"]
    assert lo < tx < hi and r["excludes_zero"]
    assert r["chi2_end"] <= r["chi2_start"] * 1.001
    assert r["n_parameters"] == 2 + 0 + 8  # the slope's two components, no weighed masses fitted, 8 frictions


def test_imply_sim_pushes_reruns_pushes_in_the_corrected_scene(tilted, tmp_path):
    """The corrected file through `imply sim pushes --model` gives the re-simulation's pushes at direction 0."""
    s, folder = tilted
    pushes = pd.DataFrame({"object_id": ["a", "b"], "speed": [0.3, 0.7], "mass": [0.5, 1.0], "friction": [0.2, 0.35]})
    pushes.to_csv(tmp_path / "pushes.csv", index=False)
    out = tmp_path / "log.csv"
    assert (
        main(["sim", "pushes", str(tmp_path / "pushes.csv"), "--model", str(folder / "corrected.xml"), "-o", str(out)])
        == 0
    )
    got = pd.read_csv(out)["displacement"].to_numpy()
    tilt = np.array(s["simulator"]["causes"][0]["value"])
    scene = Scene(xml=build_xml(SceneConfig()), name="built-in")
    want, _, _ = simulate_log(
        scene,
        {"tilt": tilt},
        PushSet(speed=pushes.speed.to_numpy(), direction=np.zeros(2), obj=np.arange(2)),
        np.log(pushes.mass.to_numpy()),
        np.log(pushes.friction.to_numpy()),
    )
    np.testing.assert_allclose(np.log(got), want[0], rtol=0, atol=1e-6)


def test_causes_the_probes_contradict_are_withdrawn(tilted):
    s = Summary.from_dict(tilted[0])
    v = contradicted(s.verdict, ["probes"])
    assert v.identification == Identification.CONTRADICTED and v.effects == [] and v.withdrawn == ["tilt"]
    text = verdict_text(replace(s, verdict=v))
    assert "contradicted by the log's calibration probes" in text and "no cause is stated" in text
    assert contradicted(s.verdict, []) == s.verdict


def test_free_strokes_contradict_an_explanation_that_leaves_the_pusher_at_its_command(analytic_table):
    """A pusher 0.04 m/s fast: under the table alone the free strokes sit far out; under the speed offset they fit."""
    offset = 0.04
    log = make_log(seed=3, offset=offset, sd=0.02)
    servo = Servo.of_scene(SCENE)
    speeds = np.repeat([0.3, 0.6, 0.9], 2)
    rng = np.random.default_rng(1)
    measured = servo.mean_speed(speeds + offset) * np.exp(rng.normal(0, 0.005, speeds.size))
    table = replace(analytic_table, meta={"scene": SCENE})
    prob = Problem.of(
        replace(log, probes=probes_of(log, strokes=np.stack([speeds, measured], 1))), table, None, grid=OPTS.grid
    )
    prob = prob.with_noise(0.02, None)
    start = prob.initial_fit()
    alone = prob.fit(Model(), np.zeros(0), start)
    with_offset = prob.fit(Model((candidates.CANDIDATES["speed_offset"],)), np.array([0.0]), start)
    (bad,) = [k for k in probe_kinds(prob, alone) if k.kind == "free_stroke"]
    (good,) = [k for k in probe_kinds(prob, with_offset) if k.kind == "free_stroke"]
    assert bad.n == 6 and bad.p_value < 1e-6 and bad.worst_sd > 5
    assert good.p_value > 1e-3


@pytest.mark.parametrize(
    "share, predicted, tolerance, expected",
    [
        (0.9, 0.92, 0.05, (False, False)),  # agree
        (0.3, 0.9, 0.05, (True, True)),  # the simulator finds a third of the claimed shrink
        (0.72, 0.83, 0.05, (True, False)),  # disagree by more than the tables' error, but most of the shrink is there
        (1.1, 0.8, 0.05, (True, False)),  # the simulator closes more
        (
            -6.9,
            -0.5,
            0.05,
            (True, True),
        ),  # the causes alone widen the gap, in the simulator far more than in the tables
        (-0.3, -0.2, 0.05, (True, False)),  # a little more
        (None, 0.9, 0.05, (False, False)),  # nothing to compare
    ],
)
def test_the_simulator_contradicts_only_a_shrink_it_cannot_reach(share, predicted, tolerance, expected):
    assert compare_shares(share, predicted, tolerance) == expected


def test_replicate_pushes_are_simulated_once_with_the_outcome_of_each_alone():
    scene = Scene(xml=build_xml(SceneConfig()), name="built-in")
    lm, lu = np.log([[0.5, 1.2], [0.8, 0.6]]), np.log([[0.2, 0.35], [0.3, 0.15]])
    # pushes 0 and 2 are replicates, as are 1 and 3; push 4 is object 1 at push 0's speed
    replicated = PushSet(
        speed=np.array([0.3, 0.7, 0.3, 0.7, 0.3]), direction=np.zeros(5), obj=np.array([0, 1, 0, 1, 1])
    )
    got_d, got_t, got_ok = simulate_log(scene, {}, replicated, lm, lu, stop_time=True)
    for i in range(5):
        one = PushSet(speed=replicated.speed[i : i + 1], direction=np.zeros(1), obj=replicated.obj[i : i + 1])
        want_d, want_t, want_ok = simulate_log(scene, {}, one, lm, lu, stop_time=True)
        np.testing.assert_array_equal(got_d[:, i], want_d[:, 0])
        np.testing.assert_array_equal(got_t[:, i], want_t[:, 0])
        np.testing.assert_array_equal(got_ok[:, i], want_ok[:, 0])
    assert got_d.shape == (2, 5) and not np.array_equal(got_d[:, 0], got_d[:, 4])
