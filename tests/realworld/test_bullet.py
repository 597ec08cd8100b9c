"""The benchmark's pushes in Bullet (imply.realworld.bullet): the same experiment, another engine's contact model."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from imply.realworld.bullet import BulletStepping, simulate_bullet
from imply.realworld.world import WorldPushes


def _pushes(scene, speed, mass, friction, direction=0.0, **params) -> WorldPushes:
    p = WorldPushes.nominal(speed, mass, friction, direction, scene)
    for k, v in params.items():
        p.params[k][:] = v
    return p


def _rigid_push(u: float, m: float, mu: float, scene, g: float = 9.81) -> float:
    """Travel of a box pushed by a rigid pusher over the stroke (servo law, fine Euler), then sliding to rest."""
    x = v = 0.0
    h = 1e-6
    while x < scene.stroke:
        v += h * (scene.pusher_kv * (u - v) - mu * m * g) / (m + scene.pusher_mass)
        x += h * v
    return scene.stroke + v * v / (2 * mu * g)


def test_result_shapes_and_monotone_in_speed_and_friction(scene):
    speeds = np.array([0.2, 0.5, 0.9, 0.5, 0.5])
    frictions = np.array([0.3, 0.3, 0.3, 0.1, 0.6])
    res = simulate_bullet(_pushes(scene, speeds, 0.5, frictions), scene)
    for f in ("displacement", "lateral", "stop_time", "ok", "steps"):
        assert getattr(res, f).shape == (5,), f
    assert res.ok.all() and (res.steps > 0).all()
    d = res.displacement
    assert d[0] < d[1] < d[2]  # faster, further
    assert d[3] > d[1] > d[4]  # more friction, shorter
    assert res.stop_time[0] < res.stop_time[1] < res.stop_time[2]
    assert np.abs(res.lateral).max() < 0.01 * d.max()


def test_agrees_with_the_rigid_contact_push(scene):
    """Bullet's contacts are rigid: its pushes follow the rigid-pusher model (servo law, then Coulomb slide)."""
    cases = [(0.9, 0.2, 0.6), (0.9, 2.0, 0.1), (0.2, 0.2, 0.1), (0.5, 1.0, 0.35)]
    v, m, mu = (np.array(c) for c in zip(*cases, strict=True))
    res = simulate_bullet(_pushes(scene, v, m, mu), scene)
    rigid = np.array([_rigid_push(*c, scene) for c in cases])
    assert np.abs(np.log(res.displacement / rigid)).max() < 0.02


def test_same_inputs_same_bytes_in_any_order(scene):
    p = _pushes(scene, [0.3, 0.8, 0.6], [0.4, 1.5, 0.9], [0.2, 0.5, 0.15], [0.0, 1.0, 2.0], tilt=0.01, viscous=0.3)
    a, b = simulate_bullet(p, scene), simulate_bullet(p, scene)
    rev = simulate_bullet(p.subset(np.array([2, 1, 0])), scene)
    for f in ("displacement", "lateral", "stop_time", "ok", "steps"):
        assert getattr(a, f).tobytes() == getattr(b, f).tobytes(), f
        # every push in a fresh scene: a push does not depend on those before it
        assert getattr(a, f).tobytes() == getattr(rev, f)[::-1].tobytes(), f


def test_downhill_slides_further_than_uphill(scene):
    direction = 1.0
    down = direction + np.array([0.0, np.pi, np.pi / 2])  # along the push, against it, across it
    res = simulate_bullet(_pushes(scene, [0.6] * 3, 0.5, 0.2, direction, tilt=0.03, tilt_azimuth=down), scene)
    flat = simulate_bullet(_pushes(scene, 0.6, 0.5, 0.2, direction), scene)
    assert res.ok.all()
    assert res.displacement[0] > flat.displacement[0] > res.displacement[1]
    assert res.lateral[2] > 0.002 > abs(res.lateral[0])  # a slope across the push pulls the box sideways


def test_forces_and_friction_laws_shorten_the_slide(scene):
    base = simulate_bullet(_pushes(scene, 0.7, 0.5, 0.2), scene).displacement[0]
    laws = [{"viscous": 0.5}, {"air_density": 200.0}, {"stribeck": 1.0, "stribeck_speed": 0.3}, {"gradient": 2.0}]
    for law in laws:
        d = simulate_bullet(_pushes(scene, 0.7, 0.5, 0.2, **law), scene).displacement[0]
        assert d < base * 0.99, law
    # friction larger along the push (axis 0) shortens it, larger across (axis pi/2) lengthens it
    along = simulate_bullet(_pushes(scene, 0.7, 0.5, 0.2, aniso=0.2, aniso_axis=0.0), scene).displacement[0]
    across = simulate_bullet(_pushes(scene, 0.7, 0.5, 0.2, aniso=0.2, aniso_axis=np.pi / 2), scene).displacement[0]
    assert along < base < across


def test_unsupported_parameters_are_refused_by_name(scene):
    with pytest.raises(ValueError, match="pusher_timeconst"):
        simulate_bullet(_pushes(scene, 0.5, 0.5, 0.3, pusher_timeconst=0.02), scene)
    p = _pushes(scene, 0.5, 0.5, 0.3)
    p.params["new_contact_law"] = np.array([0.1])
    with pytest.raises(ValueError, match="new_contact_law"):
        simulate_bullet(p, scene)
    # at their nominal values, unsupported and unknown parameters are fine
    p.params["new_contact_law"][:] = 0.0
    assert simulate_bullet(p, scene).ok.all()


def test_steps_converge(scene):
    p = _pushes(scene, [0.2, 0.9, 0.5], [0.2, 2.0, 0.7], [0.6, 0.1, 0.3])
    st = BulletStepping()
    a, b = simulate_bullet(p, scene, st), simulate_bullet(p, scene, st.finer(2))
    assert np.abs(np.log(a.displacement / b.displacement)).max() < 0.005
    assert np.abs(a.stop_time - b.stop_time).max() < 0.002
    with pytest.raises(ValueError, match="slide_step"):
        dataclasses.replace(st, slide_step=-1.0)


def _rigid_stroke_time(u: float, m: float, mu: float, scene, g: float = 9.81) -> float:
    """Time the rigid-pusher model takes over the stroke (servo law, fine Euler)."""
    x = v = t = 0.0
    h = 1e-6
    while x < scene.stroke:
        v += h * (scene.pusher_kv * (u - v) - mu * m * g) / (m + scene.pusher_mass)
        x += h * v
        t += h
    return t


def test_records_the_stroke_time_and_the_track(scene):
    """The pusher's stroke time follows the rigid-pusher model; the camera frames start at the push and end where
    the box stopped, and never run ahead of it."""
    cases = [(0.9, 0.2, 0.6), (0.3, 1.5, 0.2)]
    v, m, mu = (np.array(c) for c in zip(*cases, strict=True))
    times = np.arange(0.0, 1.5, 0.01)
    res = simulate_bullet(_pushes(scene, v, m, mu), scene, track_times=times)
    rigid = np.array([_rigid_stroke_time(*c, scene) for c in cases])
    assert np.abs(np.log(res.stroke_time / rigid)).max() < 0.03
    assert res.track.shape == (2, times.size, 3)
    assert np.abs(res.track[:, 0, :2]).max() < 1e-6
    assert np.allclose(res.track[:, -1, 0], res.displacement)
    assert (res.track[:, :, 0] <= res.displacement[:, None] + 1e-5).all()  # Bullet settles back by microns
