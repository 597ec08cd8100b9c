"""What a robot records (imply.sim.track): the pusher's mean speed and a track's crossing times, checked against
closed forms and across the table's simulator and the benchmark's world (two code paths: Euler with a travel
correction against RK4 on uniform steps)."""

from __future__ import annotations

import numpy as np
import pytest

from imply.diagnose.physics.effect_tables import simulate_observables
from imply.realworld.world import WorldPushes, simulate_world
from imply.sim.scene import build_model
from imply.sim.track import crossing_times, pusher_speed


def test_crossing_times_of_a_uniform_deceleration():
    # x(t) = u t - a t^2 / 2 until it stops at d = u^2 / (2 a): x reaches q d at t = (u / a)(1 - sqrt(1 - q))
    u, a = 0.6, 3.0
    t = np.linspace(0.0, 0.5, 501)
    stop = u / a
    x = np.where(t < stop, u * t - a * t * t / 2, u * u / (2 * a))
    d = u * u / (2 * a)
    got = crossing_times(t, x, np.array([d]), fractions=(0.25, 0.5, 0.75))[0]
    want = stop * (1 - np.sqrt(1 - np.array([0.25, 0.5, 0.75])))
    assert np.allclose(got, want, atol=2e-5)


def test_crossing_times_ignore_noise_that_steps_back():
    t = np.linspace(0.0, 1.0, 11)
    x = np.array([0.0, 0.2, 0.5, 0.45, 0.8, 1.0, 0.98, 1.0, 1.0, 1.0, 1.0])
    got = crossing_times(t, x, np.array([1.0]), fractions=(0.5, 0.6, 0.99))[0]
    # 0.5 is reached at t=0.2 and the dip to 0.45 does not make a later crossing; 0.6 lies between 0.5 and 0.8
    assert got[0] == pytest.approx(0.2)
    assert got[1] == pytest.approx(0.3 + 0.1 * (0.6 - 0.5) / (0.8 - 0.5))
    never = crossing_times(t, x, np.array([2.0]), fractions=(0.75,))
    assert np.isnan(never).all()


def test_pusher_speed_is_the_stroke_over_its_time():
    assert np.allclose(pusher_speed(0.01, np.array([0.05, 0.02])), [0.2, 0.5])
    assert np.isnan(pusher_speed(0.01, np.array([np.nan, 0.0]))).all()


def test_table_simulator_and_world_agree_on_what_a_robot_records(scene):
    """The pusher's mean speed and the crossing times from the table's simulator (Euler, frames every ms) and from
    the world (RK4, its own camera frames): within the observables' own noise (1% and 3%). The servo does not reach
    its command within the stroke, and a heavier box slows it."""
    v = np.array([0.25, 0.55, 0.85, 0.85])
    m = np.array([0.5, 1.0, 0.5, 2.0])
    u = np.array([0.3, 0.2, 0.4, 0.3])
    table = simulate_observables(build_model(scene), v, m, u, nthread=2)
    times = np.arange(0.0, 2.0, 0.005)
    world = simulate_world(WorldPushes.nominal(v, m, u, 0.0, scene), scene, nthread=2, track_times=times)
    assert table.ok.all() and world.ok.all()
    p_world = pusher_speed(scene.stroke, world.stroke_time)
    assert np.abs(table.log_p - np.log(p_world)).max() < 0.01
    assert (p_world < 0.8 * v).all()  # the servo lags its command
    assert p_world[3] < p_world[2]  # the heavier box slows the pusher
    tq = crossing_times(times, world.track[:, :, 0], world.displacement)
    assert np.abs(table.log_tq - np.log(tq)).max() < 0.03
    # the track ends where the box stopped, and starts at the push
    assert np.allclose(world.track[:, -1, 0], world.displacement)
    assert np.abs(world.track[:, 0, :2]).max() < 1e-9
