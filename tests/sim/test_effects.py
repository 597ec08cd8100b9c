"""The library's scene edits: the pusher-box contact's margin."""

import numpy as np
import pytest

from imply.diagnose.effect_tables import simulate_observables
from imply.sim.effects import EFFECTS, effect_spec
from imply.sim.scene import SceneConfig
from rigid_push import rigid_push

SPEEDS = np.array([0.2, 0.2, 0.9, 0.9])
MASSES = np.array([0.3, 2.0, 0.3, 2.0])
FRICTIONS = np.array([0.5, 0.1, 0.1, 0.5])


def _pushes(key: str, x: float):
    model = effect_spec(SceneConfig(), key, x).compile()
    return simulate_observables(model, SPEEDS, MASSES, FRICTIONS, nthread=1)


@pytest.fixture(scope="module")
def base():
    return _pushes("pusher_margin", 0.0)


def test_the_pusher_margins_pair_is_the_scenes_own_contact(base):
    """With its margin the box's, the explicit pusher-box pair pushes exactly as the scene's own contact does."""
    same = _pushes("pusher_margin", 1e-12)
    assert base.ok.all() and same.ok.all()
    assert np.abs(same.log_d - base.log_d).max() < 1e-4
    assert np.abs(same.log_t - base.log_t).max() < 1e-4


def test_a_smaller_pusher_margin_releases_the_box_closer(base):
    """A pusher contact with less of the box's margin holds the box less far ahead: every box travels less, a slow
    push's by about the margin it loses (a fast push's launch is slower too). The range ends at the scene's margin
    and at none."""
    assert EFFECTS["pusher_margin"].bounds == (-SceneConfig().contact_margin, 0.0)
    closer = _pushes("pusher_margin", -0.001)
    lost = np.exp(base.log_d) - np.exp(closer.log_d)
    slow = SPEEDS < 0.5
    assert np.all(lost > 0), lost
    assert np.all((lost[slow] > 0.0005) & (lost[slow] < 0.0025)), lost


def test_without_the_margin_the_pushes_come_nearer_a_rigid_contacts(base):
    """MuJoCo's soft pusher contact with the box's margin carries boxes further than a rigid pusher does (Bullet's
    contact, :mod:`imply.realworld.bullet`); taking the margin off the pusher-box contact closes much of that."""
    scene = SceneConfig()
    rigid = np.log([rigid_push(*c, scene) for c in zip(SPEEDS, MASSES, FRICTIONS, strict=True)])
    bare = _pushes("pusher_margin", EFFECTS["pusher_margin"].bounds[0])
    before, after = base.log_d - rigid, bare.log_d - rigid
    assert np.all(before > 0.05), before
    assert np.sqrt(np.mean(after**2)) < 0.6 * np.sqrt(np.mean(before**2)), (before, after)
