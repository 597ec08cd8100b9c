"""Each distinct push simulated once (imply.realworld.contact.simulate_distinct): the same result as every push."""

from __future__ import annotations

import numpy as np
import pytest

from imply.realworld.contact import distinct_pushes, simulate_distinct, simulate_engine
from imply.realworld.world import WorldPushes

TRACK_TIMES = np.linspace(0.0, 0.6, 13)


def _pushes(scene) -> WorldPushes:
    """A nominal box in four directions (alike), twice more at one direction (alike), a tilted table in two
    directions (not alike), a friction gradient in two directions (not alike) and a free stroke in two (alike)."""
    quarter = np.arange(4) * np.pi / 2 + 0.3
    direction = np.concatenate([quarter, [2.0, 2.0], [0.4, 1.9], [0.4, 1.9], [0.0, 1.0]])
    n = direction.size
    p = WorldPushes.nominal(np.full(n, 0.5), np.full(n, 0.7), np.full(n, 0.3), direction, scene)
    p.params["tilt"][6:8] = 0.05
    p.params["gradient"][8:10] = 2.0
    p.params["free"][10:12] = 1.0
    return p


def test_directions_count_only_where_a_parameter_turns_them(scene):
    first, inverse = distinct_pushes(_pushes(scene))
    # the nominal box (six pushes), each tilted and each gradient push on its own, the free stroke
    assert first.tolist() == [0, 6, 7, 8, 9, 10]
    assert inverse.tolist() == [0, 0, 0, 0, 0, 0, 1, 2, 3, 4, 5, 5]
    p = _pushes(scene)
    p.mass[3] = np.nextafter(p.mass[3], 1.0)  # one bit of one input makes a push of its own
    assert distinct_pushes(p)[0].size == 7


@pytest.mark.parametrize("engine", ["mujoco", "bullet", "sapien"])
def test_each_distinct_push_once_gives_every_push_s_result_bit_for_bit(scene, engine):
    p = _pushes(scene)
    if engine != "mujoco":
        pytest.importorskip({"bullet": "pybullet", "sapien": "sapien"}[engine])
    every = simulate_engine(p, scene, engine=engine, nthread=1, track_times=TRACK_TIMES)
    once, simulated = simulate_distinct(p, scene, engine=engine, nthread=1, track_times=TRACK_TIMES, chunk=4)
    assert simulated == 6
    for field in ("displacement", "lateral", "stop_time", "ok", "steps", "stroke_time", "drive_force"):
        np.testing.assert_array_equal(getattr(once, field), getattr(every, field), err_msg=field)
    np.testing.assert_array_equal(once.track, every.track.astype(np.float32))
    # the tilt and the gradient do turn their pushes: a test that would pass with every direction alike is no test
    assert once.displacement[6] != once.displacement[7] and once.displacement[8] != once.displacement[9]
