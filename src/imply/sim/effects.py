"""Unmodelled effects: physics the push table leaves out, each a parameter that is zero in the baseline.

The diagnostic (:mod:`imply.diagnose`) asks which of these explains a gap between the
table and observed pushes; the benchmark injects them into synthetic "real" push logs.

Every effect has one signed or one-sided magnitude and enters in one of three ways:

``model``
    An edit of the push scene made with MuJoCo's own mechanisms on an
    :class:`mujoco.MjSpec` of :func:`imply.sim.scene.build_xml` (the friction triple with
    ``condim`` 4/6, joint damping, the pusher's ``solref``, gravity, the fluid model,
    the box's geometry). The diagnostic tabulates these on a coarse grid
    (:mod:`imply.diagnose.effect_tables`).
``speed``
    A transform of the commanded speed (the pusher's actual speed differs from the
    command): no new physics, the same table at another speed.
``friction``
    A direction-dependent scaling of the sliding friction (anisotropic friction):
    the same table at another friction.

Some effects depend on the push direction ``phi`` (radians, in the table plane, the
push log's ``direction`` column): the magnitude seen by a push is ``value * cos(phi)``
(``dir="cos"``), ``value * sin(phi)`` (``"sin"``) or, for friction anisotropy,
``mu * (1 + value * cos(2 phi))`` (``"cos2"``). The scene always pushes along its +x
axis, so a push in direction ``phi`` on a table tilted about its y axis by ``a`` sees a
slope ``a cos(phi)`` along the push; only that along-push component is modelled by the
diagnostic (the generator of the benchmark also applies the across-push component).

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


@dataclass(frozen=True)
class Effect:
    """One candidate effect.

    name: identifier used in push logs, reports and config.
    title: a human description.
    unit: unit of the magnitude.
    kind: ``model`` | ``speed`` | ``friction`` (see the module docstring).
    bounds: the range of magnitudes the diagnostic searches (lo may be 0: one-sided).
    levels: magnitudes at which a ``model`` effect is tabulated (nonzero; 0 is the
      baseline and always included); the diagnostic interpolates linearly between them.
    direction: None, ``"cos"``, ``"sin"`` or ``"cos2"``: how the push direction modulates it.
    table_param: for directional model effects, the tabulated effect that the per-push
      magnitude is fed into (``tilt_x`` and ``tilt_y`` share the ``slope`` table).
    """

    name: str
    title: str
    unit: str
    kind: str
    bounds: tuple[float, float]
    levels: tuple[float, ...] = ()
    direction: str | None = None
    table_param: str | None = None

    @property
    def table_key(self) -> str:
        return self.table_param or self.name

    def per_push(self, value: float, directions: np.ndarray | None) -> np.ndarray:
        """The magnitude each push sees (direction-modulated), shape of ``directions``."""
        phi = np.zeros(1) if directions is None else np.asarray(directions, float)
        if self.direction is None:
            return np.full(phi.shape, float(value))
        if self.direction == "cos":
            return value * np.cos(phi)
        if self.direction == "sin":
            return value * np.sin(phi)
        if self.direction == "cos2":
            return value * np.cos(2.0 * phi)
        raise ValueError(f"unknown direction mode {self.direction!r}")


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
    # joint damping: a force -b v on every dof of the box (its first coefficient is linear)
    j = spec.joint("box")
    d = np.zeros(3)
    d[0] = x
    j.damping = d


def _pusher_softness(spec: mujoco.MjSpec, x: float) -> None:
    # the pusher has the higher contact priority, so its solref governs the strike;
    # a longer time constant is a softer, more compliant pusher face
    p = spec.geom("pusher")
    ref = np.array(p.solref, float)
    p.solref = [ref[0] + x, ref[1]]


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
        Effect("torsional", "torsional friction (condim 4)", "m", MODEL, (0.0, 0.05), (0.01, 0.025, 0.05)),
        Effect("rolling", "rolling friction (condim 6)", "m", MODEL, (0.0, 0.02), (0.004, 0.01, 0.02)),
        Effect("viscous", "viscous (velocity-proportional) friction on the box", "N s/m", MODEL, (0.0, 1.0),
               (0.1, 0.25, 0.5, 1.0)),
        Effect("pusher_softness", "pusher contact softness (extra solref time constant)", "s", MODEL,
               (0.0, 0.08), (0.01, 0.03, 0.08)),
        Effect("tilt_x", "table tilt about its y axis (slope along x)", "rad", MODEL, (-0.03, 0.03),
               (-0.03, -0.015, -0.005, 0.005, 0.015, 0.03), direction="cos", table_param="slope"),
        Effect("tilt_y", "table tilt about its x axis (slope along y)", "rad", MODEL, (-0.03, 0.03),
               (-0.03, -0.015, -0.005, 0.005, 0.015, 0.03), direction="sin", table_param="slope"),
        Effect("air_drag", "fluid drag (medium density, MuJoCo fluid model)", "kg/m^3", MODEL, (0.0, 400.0),
               (50.0, 150.0, 400.0)),
        Effect("height", "box height deviation from the canonical box (fraction)", "1", MODEL, (-0.25, 0.25),
               (-0.25, -0.1, 0.1, 0.25)),
        Effect("speed_gain", "commanded-vs-actual speed gain (v' = (1+g) v)", "1", SPEED, (-0.2, 0.2)),
        Effect("speed_offset", "commanded-vs-actual speed offset (v' = v + c)", "m/s", SPEED, (-0.08, 0.08)),
        Effect("anisotropic", "anisotropic friction (mu' = mu (1 + a cos 2 phi))", "1", FRICTION, (-0.3, 0.3),
               direction="cos2"),
    ]
}  # fmt: skip


def effect_spec(scene: SceneConfig, key: str, value: float, xml: str | None = None) -> mujoco.MjSpec:
    """An MjSpec of the push scene with the tabulated effect ``key`` at ``value``."""
    spec = mujoco.MjSpec.from_string(xml if xml is not None else build_xml(scene))
    if value != 0.0:
        if key not in SPEC_EDITS:
            raise KeyError(f"no scene edit for effect {key!r}")
        SPEC_EDITS[key](spec, float(value))
    return spec


def effect_model(scene: SceneConfig, key: str, value: float) -> mujoco.MjModel:
    """Compiled push model with the tabulated effect ``key`` (an ``Effect.table_key``) at ``value``."""
    return effect_spec(scene, key, value).compile()


def transform_speed(effect: Effect, value: float, speeds: np.ndarray) -> np.ndarray:
    """Actual pusher speeds for commanded ``speeds`` under a ``speed`` effect."""
    speeds = np.asarray(speeds, float)
    if effect.name == "speed_gain":
        return speeds * (1.0 + value)
    if effect.name == "speed_offset":
        return speeds + value
    raise ValueError(f"{effect.name} is not a speed effect")


def transform_friction(effect: Effect, value: float, frictions: np.ndarray, directions) -> np.ndarray:
    """Sliding friction each push sees under a ``friction`` effect."""
    return np.asarray(frictions, float) * (1.0 + effect.per_push(value, directions))


def get(names: list[str] | None = None) -> list[Effect]:
    """Effects by name (all, in library order, when ``names`` is None)."""
    if names is None:
        return list(EFFECTS.values())
    unknown = [n for n in names if n not in EFFECTS]
    if unknown:
        raise KeyError(f"unknown effect(s): {', '.join(unknown)} (known: {', '.join(EFFECTS)})")
    return [EFFECTS[n] for n in names]
