"""Calibration probes in the benchmark's worlds: free strokes, pull-test friction readings, added masses."""

from __future__ import annotations

import numpy as np
import pytest

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
