"""Calibration probes in the benchmark's worlds: free strokes, pull-test friction readings, added masses."""

from __future__ import annotations

import numpy as np
import pytest

from imply.diagnose.physics.candidates import Model, get
from imply.diagnose.physics.probe_fit import pull_test_log_reading
from imply.realworld.bullet import simulate_bullet
from imply.realworld.effects import apply_effect
from imply.realworld.probes import ProbeDesign, probe_layout, probe_observables, probe_pushes
from imply.realworld.world import WorldPushes, simulate_world

MASSES = np.array([0.3, 1.2, 1.9])
FRICTIONS = np.array([0.12, 0.35, 0.55])
SPEEDS = np.array([0.2, 0.55, 0.9])


def _probes(scene, design, effect=None):
    layout = probe_layout(MASSES, SPEEDS, np.zeros(3), design)
    obj = np.maximum(layout.obj, 0)
    p = WorldPushes.nominal(layout.speed, MASSES[obj], FRICTIONS[obj], layout.direction, scene)
    if effect:
        apply_effect(p, *effect)
    return layout, probe_pushes(layout, p, design)


@pytest.mark.parametrize("simulate", [simulate_world, simulate_bullet], ids=["mujoco", "bullet"])
def test_a_pull_test_reads_the_friction_and_a_free_stroke_the_pusher(scene, simulate):
    design = ProbeDesign()
    layout, pushes = _probes(scene, design)
    observed = probe_observables(layout, simulate(pushes, scene), pushes, scene.stroke)
    assert all(observed["ok"])
    reading = np.array(observed["reading"])[layout.kind == "friction"]
    # an engine's own test reads its own contact: MuJoCo's soft friction reads up to 5% under its parameter
    assert np.allclose(reading, FRICTIONS, rtol=0.05), reading
    free = np.exp(np.array(observed["log_p"])[layout.kind == "free_stroke"])
    # no box: the pusher's mean speed is the servo's alone, a little below the command (it starts from rest)
    assert np.all((free < SPEEDS) & (free > 0.7 * SPEEDS)), free
    # the heaviest box (1.9 kg) gets no load (it would leave the table's range); the others half their mass
    loads = {int(o): a for o, a in zip(layout.obj, layout.added_mass, strict=True) if a > 0}
    assert loads == {0: 0.15, 1: 0.6} or loads == {0: 0.15, 1: 0.6, 2: 0.1}


def test_a_speed_gain_shows_in_the_free_stroke_and_a_tilt_in_the_pull_test(scene):
    design = ProbeDesign()
    layout, nominal = _probes(scene, design)
    base = probe_observables(layout, simulate_world(nominal, scene), nominal, scene.stroke)
    _, fast = _probes(scene, design, ("speed_gain", 0.1))
    gained = probe_observables(layout, simulate_world(fast, scene), fast, scene.stroke)
    free = layout.kind == "free_stroke"
    ratio = np.exp(np.array(gained["log_p"])[free] - np.array(base["log_p"])[free])
    assert np.allclose(ratio, 1.1, atol=0.02), ratio
    _, tilted = _probes(scene, design, ("tilt", 0.03, np.pi))  # uphill along the pull
    up = probe_observables(layout, simulate_world(tilted, scene), tilted, scene.stroke)
    pull = layout.kind == "friction"
    assert np.allclose(np.array(up["reading"])[pull] - np.array(base["reading"])[pull], np.tan(0.03), atol=0.01)


def test_a_recommended_probe_runs_in_the_log_s_world_as_its_own_probes_do(scene):
    """The closed loop's probes (imply.realworld.lab.extra_probes): a friction test, a free stroke and a loaded push,
    asked for as next_probes.csv names them, read what the same probes of the log's own protocol read."""
    import dataclasses

    import pandas as pd

    from imply.realworld.lab import LabBenchmarkConfig, draw_lab_cases, extra_probes
    from imply.realworld.probes import PROBE_COLUMNS

    design = LabBenchmarkConfig.from_dict(
        {
            "seed": 5,
            "logs": dict.fromkeys(LabBenchmarkConfig.groups, 0) | {"single_contact": 1},
            "n_objects": 2,
            "speeds": [0.3, 0.8],
        }
    )
    design = dataclasses.replace(design, noise=dataclasses.replace(design.noise, sd=1e-6, pusher_speed_sd=1e-6))
    case = draw_lab_cases(design)[0]
    ask = pd.DataFrame(
        {
            "probe": ["friction", "free_stroke", "added_mass"],
            "object_id": ["obj01", "", "obj00"],
            "speed": [np.nan, 0.8, 0.3],
            "added_mass": [np.nan, np.nan, 0.1],
        }
    )
    rows = extra_probes(case, design, scene, ask, seed=1)
    assert list(rows.columns) == PROBE_COLUMNS
    assert rows["probe"].value_counts().to_dict() == {
        "friction": 1,
        "free_stroke": design.probes.free_strokes,
        "added_mass": design.replicates,
    }
    friction = rows.loc[rows["probe"] == "friction", "friction"].astype(float).iloc[0]
    # the reading is the world's own friction plus the test's stated error (sd friction_sd)
    assert abs(friction - case["friction"][1]) < 5 * design.probes.friction_sd + 0.05 * case["friction"][1]
    loaded = rows[rows["probe"] == "added_mass"]
    assert set(loaded["object_id"]) == {"obj00"} and np.allclose(loaded["added_mass"].astype(float), 0.1)
    free = rows.loc[rows["probe"] == "free_stroke", "pusher_speed"].astype(float)
    assert np.all((free < 0.8) & (free > 0.5)), free


@pytest.mark.parametrize(
    ("effect", "candidate", "theta"),
    [
        (("tilt", 0.03, 1.0), "tilt", [0.03 * np.cos(1.0), 0.03 * np.sin(1.0)]),
        (("viscous", 1.0), "viscous", [1.0]),
        (("anisotropic", 0.3, 0.5), "anisotropic", [0.3 * np.cos(1.0), 0.3 * np.sin(1.0)]),
    ],
    ids=["tilt", "viscous", "anisotropic"],
)
def test_the_diagnostic_reads_a_pull_test_as_the_world_runs_it(scene, effect, candidate, theta):
    """What the fits predict a pull test reads under an effect (imply.diagnose.physics.probe_fit, a force balance) against
    the world's own pull test stepped in MuJoCo: the change the effect makes to each object's reading."""
    design = ProbeDesign()
    directions = np.array([0.3, 2.0, 4.0])
    layout = probe_layout(MASSES, SPEEDS, directions, design)
    obj = np.maximum(layout.obj, 0)
    readings = []
    for e in (None, effect):
        p = WorldPushes.nominal(layout.speed, MASSES[obj], FRICTIONS[obj], layout.direction, scene)
        if e:
            apply_effect(p, *e)
        p = probe_pushes(layout, p, design)
        readings.append(np.array(probe_observables(layout, simulate_world(p, scene), p, scene.stroke)["reading"]))
    pull = layout.kind == "friction"
    world = (readings[1] - readings[0])[pull]
    model = Model(tuple(get([candidate])))
    lm, lu = np.log(MASSES)[None, :], np.log(FRICTIONS)[None, :]
    speed = np.full(3, design.pull_speed)
    predicted = np.exp(pull_test_log_reading(model, np.array([theta]), lm, lu, speed, directions))[0] - FRICTIONS
    assert np.abs(world).max() > 0.02  # the effect moves the reading by a third of a stated uncertainty or more
    # the force balance is ideal; the world's box, dragged through its own soft contact's friction cone with
    # gravity partly across the drag, reads within a quarter of the test's stated uncertainty of it, and far closer
    # than reading the effect as no change at all
    error = np.abs(predicted - world)
    assert error.max() <= design.friction_sd / 4, (predicted, world)
    assert np.sqrt(np.mean(error**2)) < 0.5 * np.sqrt(np.mean(world**2)), (predicted, world)
    # without the drag's direction and speed, the reading cannot say what the effect does to it
    blind = pull_test_log_reading(model, np.array([theta]), lm, lu, np.full(3, np.nan), np.full(3, np.nan))[0]
    assert np.allclose(np.exp(blind), FRICTIONS, rtol=1e-3)  # the slope's cos on the normal force alone


def test_a_logs_probes_name_only_the_boxes_it_pushed():
    """A box whose every push failed its world's checks is not in the log: its probes are left out, free strokes
    (no box) kept, and the diagnosis's reader takes what is left."""
    import pandas as pd

    from imply.realworld.lab import probes_of_logged

    log = pd.DataFrame({"object_id": ["obj00", "obj00"], "speed": [0.2, 0.34]})
    rows = pd.DataFrame(
        {
            "probe": ["free_stroke", "friction", "friction", "added_mass"],
            "object_id": ["", "obj00", "obj01", "obj01"],
            "speed": [0.2, 0.1, 0.1, 0.48],
        }
    )
    kept = probes_of_logged(rows, log)
    assert kept["probe"].tolist() == ["free_stroke", "friction"] and kept["object_id"].tolist() == ["", "obj00"]
