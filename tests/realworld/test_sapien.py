"""The benchmark's pushes in SAPIEN (PhysX): a third engine, never used to choose; the rig protocol shared with Bullet."""

from __future__ import annotations

import numpy as np
import pytest

from imply.realworld.bullet import simulate_bullet
from imply.realworld.sapien_world import simulate_sapien
from imply.realworld.world import WorldPushes, simulate_world

SPEEDS = np.array([0.2, 0.48, 0.9, 0.34, 0.76, 0.62])
MASSES = np.array([0.3, 1.0, 1.8, 0.6, 0.25, 1.4])
FRICTIONS = np.array([0.1, 0.3, 0.5, 0.2, 0.45, 0.15])


def _pushes(scene, speed=SPEEDS, mass=MASSES, friction=FRICTIONS, direction=0.0, **params) -> WorldPushes:
    p = WorldPushes.nominal(speed, mass, friction, direction, scene)
    for k, v in params.items():
        p.params[k][:] = v
    return p


def test_null_pushes_differ_from_the_table_physics_by_a_pinned_amount(scene):
    """PhysX's rigid contact is not MuJoCo's soft one: its null slides are shorter by a stated margin.

    Pinned on these pushes: the RMS gap in log d against the converged MuJoCo world (the table's physics) lies
    between 0.05 and 0.4 (about 2.5 to 20 noise sds of the benchmark's logs), and PhysX agrees with Bullet, the
    other rigid engine, within 0.05."""
    p = _pushes(scene)
    sap, mj, bt = simulate_sapien(p, scene), simulate_world(p, scene), simulate_bullet(p, scene)
    assert sap.ok.all()
    gap = np.log(sap.displacement / mj.displacement)
    assert 0.05 < np.sqrt(np.mean(gap**2)) < 0.4, gap
    assert np.all(gap < 0), gap  # rigid contact: no soft launch
    assert np.abs(np.log(sap.displacement / bt.displacement)).max() < 0.05


def test_forces_tilt_and_friction_laws_act(scene):
    base = simulate_sapien(_pushes(scene, 0.6, 0.5, 0.3), scene).displacement[0]
    for params in ({"viscous": 0.8}, {"air_density": 300.0}, {"aniso": 0.3, "aniso_axis": 0.0}):
        d = simulate_sapien(_pushes(scene, 0.6, 0.5, 0.3, **params), scene).displacement[0]
        assert d < base, params
    downhill = simulate_sapien(_pushes(scene, 0.6, 0.5, 0.3, tilt=0.03, tilt_azimuth=0.0), scene).displacement[0]
    uphill = simulate_sapien(_pushes(scene, 0.6, 0.5, 0.3, tilt=0.03, tilt_azimuth=np.pi), scene).displacement[0]
    assert downhill > base > uphill


def test_unsupported_parameters_are_refused_by_name(scene):
    with pytest.raises(ValueError, match="SAPIEN world does not support the parameter.*pusher_timeconst"):
        simulate_sapien(_pushes(scene, 0.5, 0.5, 0.3, pusher_timeconst=0.02), scene)
    with pytest.raises(ValueError, match="table_timeconst"):
        simulate_sapien(_pushes(scene, 0.5, 0.5, 0.3, table_timeconst=2.0), scene)


def test_same_inputs_same_bytes_and_a_track(scene):
    p = _pushes(scene, [0.3, 0.8], [0.4, 1.5], [0.2, 0.5], [0.0, 1.0])
    times = np.linspace(0.0, 0.4, 9)
    a, b = simulate_sapien(p, scene, track_times=times), simulate_sapien(p, scene, track_times=times)
    assert a.displacement.tobytes() == b.displacement.tobytes() and a.track.tobytes() == b.track.tobytes()
    # the track ends where the box stopped; the stroke time is the pusher's
    assert np.allclose(a.track[:, -1, 0], a.displacement, atol=1e-6)
    assert np.all((a.stroke_time > 0) & (a.stroke_time < 0.1))
