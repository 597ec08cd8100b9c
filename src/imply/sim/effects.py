"""Unmodelled effects: physics the push table leaves out, each a parameter that is zero in the baseline.

The library the diagnostic's candidates are built on (:mod:`imply.diagnose.physics.candidates`,
which also says what each is called and how a verdict describes it). Every effect has
one signed or one-sided magnitude, the range the diagnostic searches (``bounds``), and
enters in one of three ways:

``model``
    An edit of the push scene made with MuJoCo's own mechanisms on an
    :class:`mujoco.MjSpec` of :func:`imply.sim.scene.build_xml` (the friction triple with
    ``condim`` 4/6, joint damping, the pusher's ``solref``, the box-table contact's ``solref``, gravity, the fluid model,
    the box's geometry): :func:`effect_spec`. The diagnostic tabulates these at the
    effect's ``levels`` on a coarse grid (:mod:`imply.diagnose.physics.effect_tables`).
``speed``
    The pusher's actual speed differs from the command (``speed_gain``: v (1 + g),
    ``speed_offset``: v + c): no new physics, the same table at another speed.
``friction``
    A direction-dependent scaling of the sliding friction (``anisotropic``):
    the same table at another friction.

The scene always pushes along its +x axis. ``tilt_x`` and ``tilt_y`` (a table sloping
along the table's x or y axis) share the ``slope`` scene edit, a slope along the push;
the diagnostic's ``tilt`` candidate combines them and adds the slope across the push
(:mod:`imply.diagnose.physics.effect_tables` tabulates ``slope_across``). The benchmark's world
(:mod:`imply.realworld`) injects its effects through its own mechanisms, not through
this module.

MuJoCo has no velocity-dependent (Stribeck) friction law; velocity-dependent friction
is represented here by viscous damping on the box's free joint (a force -b v), which
is MuJoCo's own mechanism for it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import mujoco
import numpy as np

from imply.sim.scene import SceneConfig, build_xml

MODEL, SPEED, FRICTION = "model", "speed", "friction"
# the scene's box-table contact: MuJoCo's default solref (time constant s, damping ratio), which the box's geom keeps
TABLE_SOLREF = (0.02, 1.0)


@dataclass(frozen=True)
class Effect:
    """One effect of the library.

    name: identifier used in push logs, reports and config.
    kind: ``model`` | ``speed`` | ``friction`` (see the module docstring).
    bounds: the range of magnitudes the diagnostic searches (lo may be 0: one-sided).
    levels: magnitudes at which a ``model`` effect is tabulated (nonzero; 0 is the
      baseline and always included); the diagnostic interpolates linearly between them.
    table_param: the scene edit of :data:`SPEC_EDITS` that tabulates it, where not its own
      name (``tilt_x`` and ``tilt_y`` share the ``slope`` table).
    """

    name: str
    kind: str
    bounds: tuple[float, float]
    levels: tuple[float, ...] = ()
    table_param: str | None = None

    @property
    def table_key(self) -> str:
        return self.table_param or self.name


# -- scene edits (MjSpec) ---------------------------------------------------------------


def _torsional(spec: mujoco.MjSpec, x: float) -> None:
    g = spec.geom("box")
    g.condim = 4  # sliding + torsional friction
    fr = np.array(g.friction, float)
    fr[1] = x
    g.friction = fr


def _rolling(spec: mujoco.MjSpec, x: float) -> None:
    g = spec.geom("box")
    g.condim = 6  # sliding + torsional + rolling friction
    fr = np.array(g.friction, float)
    fr[2] = x
    g.friction = fr


def _viscous(spec: mujoco.MjSpec, x: float) -> None:
    # joint damping: a force -b v on every dof of the box (its first coefficient is linear); the box's free joint is
    # its body's first joint, whatever a user's scene calls it
    j = spec.body("box").first_joint()
    if j is None:
        raise ValueError("the push scene's body 'box' has no joint")
    d = np.zeros(3)
    d[0] = x
    j.damping = d


def _pusher_softness(spec: mujoco.MjSpec, x: float) -> None:
    # the pusher has the higher contact priority, so its solref governs the strike;
    # a longer time constant is a softer, more compliant pusher face
    p = spec.geom("pusher")
    ref = np.array(p.solref, float)
    p.solref = [ref[0] + x, ref[1]]


def _table_timeconst(spec: mujoco.MjSpec, x: float) -> None:
    # the box has the higher priority than the table, so its solref governs the box-table contact;
    # x is the log of the factor on the time constant (positive: a softer, more compliant contact)
    g = spec.geom("box")
    ref = np.array(g.solref, float)
    g.solref = [ref[0] * np.exp(x), ref[1]]


def _table_dampratio(spec: mujoco.MjSpec, x: float) -> None:
    # x is the log of the factor on the box-table contact's damping ratio (negative: a bouncier contact)
    g = spec.geom("box")
    ref = np.array(g.solref, float)
    g.solref = [ref[0], ref[1] * np.exp(x)]


def _slope(spec: mujoco.MjSpec, s: float) -> None:
    # a table sloping down by angle s along +x (the push axis): rotate gravity
    g = float(np.linalg.norm(np.array(spec.option.gravity, float)))
    spec.option.gravity = [g * np.sin(s), 0.0, -g * np.cos(s)]


def _air_drag(spec: mujoco.MjSpec, rho: float) -> None:
    # MuJoCo's inertia-box fluid model: quadratic drag from the medium's density
    spec.option.density = rho


def _height(spec: mujoco.MjSpec, x: float) -> None:
    # the box is taller/shorter than the canonical one by a fraction x; the pusher stays
    # at the canonical strike height (it is part of the rig, not of the object)
    g = spec.geom("box")
    size = np.array(g.size, float)
    size[2] *= 1.0 + x
    g.size = size
    body = spec.body("box")
    pos = np.array(body.pos, float)
    pos[2] = size[2]
    body.pos = pos


SPEC_EDITS: dict[str, Callable[[mujoco.MjSpec, float], None]] = {
    "torsional": _torsional,
    "rolling": _rolling,
    "viscous": _viscous,
    "pusher_softness": _pusher_softness,
    "table_timeconst": _table_timeconst,
    "table_dampratio": _table_dampratio,
    "slope": _slope,
    "air_drag": _air_drag,
    "height": _height,
}

# The library. Levels are chosen so the largest is well beyond what a careful rig
# leaves unmodelled; bounds bracket the levels (the diagnostic never extrapolates).
# Tilt stops at 0.03 rad: on steeper slopes a resting box creeps on MuJoCo's soft
# contacts and never settles (measured: most cells at 0.06 rad time out).
EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in [
        Effect("torsional", MODEL, (0.0, 0.05), (0.01, 0.025, 0.05)),
        Effect("rolling", MODEL, (0.0, 0.02), (0.004, 0.01, 0.02)),
        Effect("viscous", MODEL, (0.0, 1.0), (0.1, 0.25, 0.5, 1.0)),
        Effect("pusher_softness", MODEL, (0.0, 0.08), (0.01, 0.03, 0.08)),
        # the box-table contact an engineer tunes in the MJCF: log factors on its solref (time constant, damping
        # ratio); a factor of 5 each way on the time constant keeps it above twice the 1 ms slide step, and a damping
        # ratio below 0.4 makes boxes bounce and fail the settling check
        Effect("table_timeconst", MODEL, (-1.6, 1.6), (-1.6, -0.8, -0.3, 0.3, 0.8, 1.6)),
        Effect("table_dampratio", MODEL, (-0.9, 0.5), (-0.9, -0.45, 0.5)),
        Effect("tilt_x", MODEL, (-0.03, 0.03), (-0.03, -0.015, -0.005, 0.005, 0.015, 0.03), table_param="slope"),
        Effect("tilt_y", MODEL, (-0.03, 0.03), (-0.03, -0.015, -0.005, 0.005, 0.015, 0.03), table_param="slope"),
        Effect("air_drag", MODEL, (0.0, 400.0), (50.0, 150.0, 400.0)),
        Effect("height", MODEL, (-0.25, 0.25), (-0.25, -0.1, 0.1, 0.25)),
        Effect("speed_gain", SPEED, (-0.2, 0.2)),
        Effect("speed_offset", SPEED, (-0.08, 0.08)),
        Effect("anisotropic", FRICTION, (-0.3, 0.3)),
    ]
}


def effect_spec(scene: SceneConfig, key: str, value: float, xml: str | None = None) -> mujoco.MjSpec:
    """An MjSpec of the push scene with the tabulated effect ``key`` at ``value``."""
    spec = mujoco.MjSpec.from_string(xml if xml is not None else build_xml(scene))
    if value != 0.0:
        if key not in SPEC_EDITS:
            raise KeyError(f"no scene edit for effect {key!r}")
        SPEC_EDITS[key](spec, float(value))
    return spec
