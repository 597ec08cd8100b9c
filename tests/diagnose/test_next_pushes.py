"""The next pushes: designed to separate the contenders, written as a push log's columns that `imply sim pushes`
reads, and run in the benchmark's world for the closed loop."""

from __future__ import annotations

import numpy as np
import pandas as pd
from test_steps import OPTS, make_log, problem_of

from imply.cli import main
from imply.diagnose.conclusion.next_pushes import (
    candidate_log,
    design_pushes,
    next_pushes_frame,
    predictions,
    write_next_pushes,
)
from imply.diagnose.inputs.pushlog import read_pushlog
from imply.diagnose.physics import candidates
from imply.diagnose.physics.candidates import Model
from imply.sim.push_file import read_pushes


def _contenders(prob):
    """A speed gain and a speed offset fitted to the same log: two explanations that differ away from its speeds."""
    out = []
    for name, start in (("speed_gain", 0.1), ("speed_offset", 0.04)):
        model = Model((candidates.CANDIDATES[name],))
        fit = prob.fit(model, np.array([start]), prob.initial_fit(model, np.array([start])))
        out.append((name, fit, 0.5))
    return out


def test_the_design_separates_the_contenders_better_than_the_logs_own_pushes(analytic_table):
    prob = problem_of(make_log(seed=7, offset=0.05), analytic_table).with_noise(0.02, None)
    design = design_pushes(prob, _contenders(prob), n=6, speeds=9, directions=4, opts=OPTS.replace(model_floor=0.0))
    assert len(design.pushes) == 6 and design.contenders == ["speed_gain", "speed_offset"]
    (pair,) = design.pairs
    assert (pair.first, pair.second) == ("speed_gain", "speed_offset")
    assert pair.next_pushes_sd > 2 * pair.log_design_sd
    # a gain and an offset part most at the ends of the speed range: the design goes there, never the same push twice
    speeds = [p.speed for p in design.pushes]
    lo, hi = prob.v_range
    assert all(v < lo + 0.2 * (hi - lo) or v > hi - 0.2 * (hi - lo) for v in speeds)
    keys = [(p.object_id, p.speed, p.direction) for p in design.pushes]
    assert len(set(keys)) == len(keys)
    # what each contender predicts is its own prediction at that push
    cand = candidate_log(prob.log, prob.v_range, speeds=9, directions=4)
    assert cand.n == len(prob.log.objects) * 9 * 4
    first = design.pushes[0]
    for name, fit, _ in _contenders(prob):
        from imply.diagnose.inference.fit import Problem

        cp = Problem.of(cand, prob.table, None, grid=prob.grid)
        log_d, _ = predictions(cp, fit)
        k = next(
            i
            for i in range(cand.n)
            if cand.objects[cand.obj[i]] == first.object_id
            and np.isclose(cand.speed[i], first.speed)
            and np.isclose(cand.direction[i], first.direction)
        )
        assert np.isclose(first.expected_displacement[name], np.exp(log_d[k]))


def test_nothing_to_separate_writes_the_header_alone(analytic_table, tmp_path):
    prob = problem_of(make_log(seed=7), analytic_table)
    assert design_pushes(prob, _contenders(prob)[:1], n=6, speeds=9, directions=4, opts=OPTS) is None
    write_next_pushes(tmp_path / "next.csv", None, prob.log)
    assert (tmp_path / "next.csv").read_text().strip() == "object_id,speed,direction,mass"


def test_next_pushes_are_a_pushes_file_imply_sim_pushes_runs(analytic_table, tmp_path):
    prob = problem_of(make_log(seed=7, offset=0.05), analytic_table).with_noise(0.02, None)
    design = design_pushes(prob, _contenders(prob), n=3, speeds=5, directions=4, opts=OPTS.replace(model_floor=0.0))
    frame = next_pushes_frame(design, prob.log)
    assert list(frame.columns) == [
        "object_id",
        "speed",
        "direction",
        "mass",
        "expected_displacement_if_speed_gain",
        "expected_displacement_if_speed_offset",
    ]
    path = tmp_path / "next_pushes.csv"
    write_next_pushes(path, design, prob.log)
    pushes = read_pushes(path)  # what `imply sim pushes` reads
    assert len(pushes) == 3 and (pushes["mass"] > 0).all()
    out = tmp_path / "more.csv"
    assert main(["sim", "pushes", str(path), "-o", str(out), "--threads", "1"]) == 0
    more = pd.read_csv(out)
    assert (more["displacement"] > 0).all() and "expected_displacement_if_speed_gain" in more  # passed through
    # appended to a log, it is a push log the diagnostic reads
    columns = ["object_id", "speed", "direction", "displacement"]
    log = pd.concat([prob.log.frame[columns], more[columns]], ignore_index=True)
    log.to_csv(tmp_path / "log.csv", index=False)
    assert read_pushlog(tmp_path / "log.csv", analytic_table.speed_range).n == prob.log.n + len(more)


def test_extra_pushes_run_in_the_same_world_with_the_logs_columns():
    from imply.realworld import cases as C
    from imply.sim import SceneConfig

    design = C.BenchmarkConfig.from_dict(
        {
            "seed": 0,
            "n_objects": 3,
            "speeds": [0.3, 0.6],
            "masses": [0.3, 1.5],
            "frictions": [0.15, 0.45],
            "replicates": 2,
        }
    )
    case = {
        "id": "c",
        "group": "test",
        "effects": [],
        "mass": [0.5, 1.0, 1.2],
        "friction": [0.2, 0.3, 0.4],
        "direction": [0.0] * 6,
        "measured_mass": True,
        "stop_time": True,
        "noise": "gaussian",
        "noise_seed": 3,
    }
    scene = SceneConfig()
    new = C.extra_pushes(case, design, scene, np.array([0, 2]), np.array([0.4, 0.8]), np.array([0.0, 1.0]), seed=1)
    assert list(new.columns) == [
        "object_id",
        "speed",
        "direction",
        "displacement",
        "stop_time",
        "pusher_speed",
        "size_x",
        "size_y",
        "size_z",
        "mass",
    ]
    # the pusher's measured speed: below its command within the stroke, noise of the configured size
    assert (new["pusher_speed"] < new["speed"]).all() and (new["pusher_speed"] > 0.2 * new["speed"]).all()
    assert list(new["object_id"]) == ["obj00", "obj02", "obj00", "obj02"]  # two noise draws of each push
    ratio = new["displacement"].to_numpy()[:2] / new["displacement"].to_numpy()[2:]
    assert np.all(np.abs(np.log(ratio)) < 0.2) and not np.allclose(ratio, 1.0)  # the same push, fresh noise
    again = C.extra_pushes(case, design, scene, np.array([0, 2]), np.array([0.4, 0.8]), np.array([0.0, 1.0]), seed=1)
    pd.testing.assert_frame_equal(new, again)  # the same seed, the same bytes
