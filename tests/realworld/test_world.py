"""The gap benchmark's world (imply.realworld): converged, its own mechanisms, sealed labels."""

from __future__ import annotations

import dataclasses
import json

import mujoco
import numpy as np
import pytest

from imply.cli import main
from imply.realworld import cases as C
from imply.realworld.effects import EFFECTS, LIBRARY, OUTSIDE, apply_effect
from imply.realworld.world import WorldPushes, WorldStepping, _run, simulate_world
from imply.sim.effects import SPEC_EDITS
from imply.sim.reference import reference_log_d
from imply.sim.scene import build_xml

SPEEDS = np.array([0.2, 0.5, 0.9, 0.35])
MASSES = np.array([0.3, 1.2, 0.5, 1.8])
FRICTIONS = np.array([0.15, 0.4, 0.25, 0.55])


def _nominal(scene, direction=0.0):
    return WorldPushes.nominal(SPEEDS, MASSES, FRICTIONS, direction, scene)


def test_world_does_not_import_the_diagnostic():
    """The worlds that make the logs share nothing with the diagnostic; only the modules that score it read it."""
    import ast
    import pathlib

    import imply.realworld as rw

    scoring = {"benchmark.py", "benchmark_report.py", "closed_loop.py", "lab_score.py"}
    worlds = [p for p in pathlib.Path(rw.__file__).parent.glob("*.py") if p.name not in scoring]
    assert {"world.py", "bullet.py", "sapien_world.py", "probes.py", "lab.py", "separability.py"} <= {
        p.name for p in worlds
    }
    for path in worlds:
        tree = ast.parse(path.read_text())
        names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
        names += [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)]
        assert not [n for n in names if n.startswith("imply.diagnose") or n.startswith("imply.table")], path


def test_nominal_world_agrees_with_the_uniform_step_reference(scene):
    """RK4 on the world's steps against the project's plain Euler reference at 15.6 us: within the table's error."""
    res = simulate_world(_nominal(scene), scene, WorldStepping(), nthread=2)
    assert res.ok.all()
    ref = reference_log_d(SPEEDS, MASSES, FRICTIONS, scene=scene, step=scene.timestep / 64, nthread=2)
    err = np.log(res.displacement) - ref.log_d
    assert np.abs(err).max() < 0.004, err
    # and the world converges on its own: four times finer steps change little
    fine = simulate_world(_nominal(scene), scene, WorldStepping().finer(4), nthread=2)
    assert np.abs(np.log(res.displacement / fine.displacement)).max() < 0.003
    assert np.abs(np.log(res.stop_time / fine.stop_time)).max() < 0.01


def test_forces_match_the_library_mechanisms(scene):
    """Viscous friction and air drag applied as forces equal MuJoCo's joint damping and fluid model."""
    st = WorldStepping()

    def library(key: str, x: float):
        s2 = dataclasses.replace(scene, option={"integrator": "RK4"})
        spec = mujoco.MjSpec.from_string(build_xml(s2))
        SPEC_EDITS[key](spec, x)
        return _run(spec.compile(), _nominal(scene), st, nthread=2, progress=False).displacement

    for key, param, x, tol in (("viscous", "viscous", 0.6, 0.01), ("air_drag", "air_density", 300.0, 0.006)):
        p = _nominal(scene)
        p.params[param][:] = x
        ours = simulate_world(p, scene, st, nthread=2).displacement
        base = simulate_world(_nominal(scene), scene, st, nthread=2).displacement
        theirs = library(key, x)
        assert np.all(np.log(ours / base) < -0.002) and np.log(ours / base).min() < -0.1, key  # the effect is there
        assert np.abs(np.log(ours / theirs)).max() < tol, (key, np.log(ours / theirs))


def test_tilt_rotates_gravity_in_full(scene):
    st = WorldStepping()
    base = simulate_world(_nominal(scene), scene, st, nthread=2)
    out = {}
    for name, azimuth in (("down", 0.0), ("up", np.pi), ("across", np.pi / 2)):
        p = _nominal(scene)
        apply_effect(p, "tilt", 0.03, azimuth)
        out[name] = simulate_world(p, scene, st, nthread=2)
    assert np.all(out["down"].displacement > base.displacement)
    assert np.all(out["up"].displacement < base.displacement)
    # across the push: the box drifts sideways toward the downhill side
    assert np.all(out["across"].lateral > 1e-4)
    assert np.abs(np.log(out["across"].displacement / base.displacement)).max() < 0.05


def test_friction_laws_change_the_slide(scene):
    st = WorldStepping()
    base = simulate_world(_nominal(scene), scene, st, nthread=2)
    p = _nominal(scene)
    apply_effect(p, "stribeck", 1.0, extra={"stribeck_speed": 0.2})
    strib = simulate_world(p, scene, st, nthread=2)
    assert np.all(strib.displacement < base.displacement)
    p = _nominal(scene)
    apply_effect(p, "friction_gradient", 3.0, azimuth=0.0)  # rougher ahead of every push (direction 0)
    grad = simulate_world(p, scene, st, nthread=2)
    assert np.all(grad.displacement < base.displacement)
    p = _nominal(scene, direction=np.pi / 2)
    apply_effect(p, "friction_gradient", 3.0, azimuth=0.0)  # across the pushes: no change
    across = simulate_world(p, scene, st, nthread=2)
    assert np.abs(np.log(across.displacement / base.displacement)).max() < 0.01


def test_effect_catalogue():
    assert len(OUTSIDE) >= 4 and set(LIBRARY) >= {"tilt", "anisotropic", "viscous", "speed_gain"}
    assert all(e.default_range[0] < e.default_range[1] for e in EFFECTS.values())


DESIGN = {
    "seed": 3,
    "logs": {"null_gaussian": 1, "null_heavy": 1, "single": 2, "double": 1, "outside": 1},
    "n_objects": 3,
    "speeds": [0.3, 0.6, 0.9],
    "noise": {"outliers": [2, 2]},
}


def test_logs_are_drawn_reproducibly_and_say_nothing_of_their_labels(scene):
    design = C.BenchmarkConfig.from_dict(DESIGN)
    a, b = C.draw_cases(design), C.draw_cases(design)
    assert a == b
    assert [c["id"] for c in a] == C.case_ids(design) == [f"log-{k:03d}" for k in range(6)]
    assert sorted(c["group"] for c in a) == sorted(
        ["null_gaussian", "null_heavy", "single", "single", "double", "outside"]
    )
    heavy = next(c for c in a if c["group"] == "null_heavy")
    sims = C.simulate_cases([heavy], design, scene, nthread=2)
    frame, label = C.make_log(heavy, sims[heavy["id"]], design, scene)
    assert "effect" not in " ".join(frame.columns) and "group" not in frame.columns
    assert len(frame) == 2 * 3 * 3 and len(label["outliers"]) == 2
    assert label["noise"]["kind"] == "heavy" and label["effects"] == []
    # a gross outlier is off by a factor: its row differs from its replicate by more than the noise
    for _rep, push in label["outliers"]:
        rows = [i for i, (p, r) in enumerate(label["rows_kept"]) if p == push]
        d = frame["displacement"].to_numpy()[rows]
        assert abs(np.log(d[0] / d[1])) > 0.3


@pytest.mark.parametrize(
    "edit, message",
    [
        ({"logs": {"nul": 3}}, "gap.benchmark.logs: unknown key(s) nul"),
        ({"noise": {"sdd": 0.1}}, "unknown gap.benchmark.noise option(s): sdd"),
        ({"ranges": {"tilt": [0.02, 0.01]}}, "gap.benchmark: ranges.tilt must be [low, high]"),
        ({"stepping": {"push_step": -1}}, "push_step: -1 is less than or equal to the minimum of 0"),
    ],
)
def test_bad_design_is_one_line(tmp_path, tiny_table_path, capsys, edit, message):
    args = [
        "study",
        "gap",
        "generate",
        "--table",
        str(tiny_table_path),
        "--bench-json",
        json.dumps({**DESIGN, **edit}),
        "--logs",
        str(tmp_path / "logs"),
        "--sealed",
        str(tmp_path / "s.json"),
        "--accuracy",
        str(tmp_path / "a.json"),
    ]
    assert main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and message in err[0], err
    assert not (tmp_path / "logs").exists()


def test_the_accuracy_record_names_the_worst_push_with_what_sets_it_apart(scene):
    from imply.realworld.accuracy import worst_push

    pushes = WorldPushes.nominal([0.3, 0.5, 0.7], [0.4, 0.8, 1.2], [0.2, 0.3, 0.4], [0.0, 1.0, 2.0], scene)
    pushes.params["viscous"][1] = 0.5
    pushes.params["servo_kv"][2] = 2 * scene.pusher_kv
    d = np.array([0.001, -0.02, 0.01])
    t = np.array([0.0, np.nan, 0.002])
    worst = worst_push(pushes, d, t, scene)
    assert worst["index"] == 1 and worst["log_d_difference"] == -0.02 and worst["log_stop_time_difference"] is None
    assert (worst["speed"], worst["mass"], worst["friction"], worst["direction"]) == (0.5, 0.8, 0.3, 1.0)
    # only what differs from the nominal world (the scene's carriage defaults included)
    assert worst["parameters"] == {"viscous": 0.5}
    assert worst_push(pushes, d * np.array([0.0, 0.0, 1.0]), t, scene)["parameters"] == {
        "servo_kv": 2 * scene.pusher_kv
    }
    assert worst_push(pushes, np.full(3, np.nan), t, scene) is None


def test_a_stiff_underdamped_table_contact_is_stepped_to_the_worlds_accuracy(scene):
    """The other-contact development set's worst push (a contact at 0.29 of the scene's time constant, damping ratio
    0.37, with friction laws): its steps are shortened by the factor, and it lands within the table's error (0.0032
    in log d) of the same push four times finer; at the nominal steps it missed by 0.023."""
    push = WorldPushes.nominal(0.48, 1.3235, 0.5792, 0.3728, scene)
    for name, value in {
        "viscous": 0.9567,
        "table_timeconst": 0.2907,
        "table_dampratio": 0.3701,
        "friction_slope": -0.5429,
        "friction_slope_speed": 0.1761,
        "friction_regularisation": 0.1048,
        "friction_rest_share": 0.4575,
    }.items():
        push.params[name][:] = value
    stepping = WorldStepping()
    run = simulate_world(push, scene, stepping, nthread=1, progress=False)
    finer = simulate_world(push, scene, stepping.finer(4), nthread=1, progress=False)
    assert run.ok[0] and finer.ok[0]
    assert abs(np.log(run.displacement[0]) - np.log(finer.displacement[0])) < 0.0032
    soft = dataclasses.replace(push, params={**push.params, "table_timeconst": np.ones(1)})
    assert run.steps[0] > 2.5 * simulate_world(soft, scene, stepping, nthread=1, progress=False).steps[0]
