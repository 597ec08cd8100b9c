"""The effects the benchmark's world can carry, each a way to set :class:`~imply.realworld.world.WorldPushes` parameters.

An effect has one magnitude (and, if directional, an azimuth in the table frame, radians,
drawn at random). ``in_library`` effects carry the name of the diagnostic's candidate
for the same physics (:mod:`imply.sim.effects`; this module does not import it, and its
magnitudes are in the same units); the others are outside the library, and the right
answer for them is "none of the candidates".

In the library (magnitude: unit):

- ``torsional``, ``rolling``: torsional / rolling friction coefficient (m), contact
  dimension 4 / 6;
- ``viscous``: b (N s/m), a force -b v on the box;
- ``pusher_softness``: s (s) added to the pusher contact's solref time constant;
- ``tilt``: slope (rad) toward the azimuth, gravity rotated in full;
- ``air_drag``: air density (kg/m^3), the inertia-box quadratic drag as a force;
- ``height``: fraction by which the box is taller (signed);
- ``speed_gain``: g, the servo runs at (1 + g) times the logged speed (signed);
- ``speed_offset``: c (m/s), the servo runs at the logged speed + c (signed);
- ``anisotropic``: a, friction mu (1 + a cos 2(theta - azimuth)) for sliding direction
  theta on the table.

Outside the library:

- ``carriage_mass``: the pusher carriage's mass (kg; nominal 0.2);
- ``servo_gain``: relative change of the servo's velocity gain kv (signed);
- ``pusher_restitution``: 1 - damping ratio of the pusher's contact (it bounces);
- ``stribeck``: s, friction mu (1 + s exp(-(v / v_s)^2)), v_s drawn in ``stribeck_speed``;
- ``friction_gradient``: k (1/m), friction mu (1 + k x) for travel x toward the azimuth;
- ``force_limit``: the servo's force limit (N; nominal 100).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from imply.realworld.world import WorldPushes


@dataclass(frozen=True)
class WorldEffect:
    name: str
    in_library: bool
    unit: str
    signed: bool  # magnitudes of either sign
    directional: bool  # has an azimuth
    default_range: tuple[float, float]  # |magnitude| range of the benchmark's draws
    apply: Callable[[WorldPushes, float, float, dict], None]
    identifiable: bool = True  # a straight push can reveal it (the library's own notes)


def _set(name: str, scale: float = 1.0, offset: float = 0.0):
    def apply(p: WorldPushes, x: float, azimuth: float, extra: dict) -> None:
        p.params[name][:] = offset + scale * x

    return apply


def _directional(name: str, azimuth_param: str):
    def apply(p: WorldPushes, x: float, azimuth: float, extra: dict) -> None:
        p.params[name][:] = x
        p.params[azimuth_param][:] = azimuth

    return apply


def _speed_gain(p: WorldPushes, x: float, azimuth: float, extra: dict) -> None:
    p.speed[:] = p.speed * (1.0 + x)


def _speed_offset(p: WorldPushes, x: float, azimuth: float, extra: dict) -> None:
    p.speed[:] = p.speed + x


def _servo_gain(p: WorldPushes, x: float, azimuth: float, extra: dict) -> None:
    p.params["servo_kv"][:] = p.params["servo_kv"] * (1.0 + x)


def _stribeck(p: WorldPushes, x: float, azimuth: float, extra: dict) -> None:
    p.params["stribeck"][:] = x
    p.params["stribeck_speed"][:] = extra["stribeck_speed"]


EFFECTS: dict[str, WorldEffect] = {
    e.name: e
    for e in [
        WorldEffect("torsional", True, "m", False, False, (0.005, 0.05), _set("torsional"), identifiable=False),
        WorldEffect("rolling", True, "m", False, False, (0.002, 0.02), _set("rolling"), identifiable=False),
        WorldEffect("viscous", True, "N s/m", False, False, (0.1, 1.0), _set("viscous")),
        WorldEffect("pusher_softness", True, "s", False, False, (0.008, 0.08), _set("pusher_timeconst")),
        WorldEffect("tilt", True, "rad", False, True, (0.003, 0.03), _directional("tilt", "tilt_azimuth")),
        WorldEffect("air_drag", True, "kg/m^3", False, False, (40.0, 400.0), _set("air_density")),
        WorldEffect("height", True, "1", True, False, (0.025, 0.25), _set("height"), identifiable=False),
        WorldEffect("speed_gain", True, "1", True, False, (0.015, 0.15), _speed_gain),
        WorldEffect("speed_offset", True, "m/s", True, False, (0.005, 0.05), _speed_offset),
        WorldEffect("anisotropic", True, "1", False, True, (0.03, 0.3), _directional("aniso", "aniso_axis")),
        WorldEffect("carriage_mass", False, "kg", False, False, (0.3, 0.8), _set("carriage_mass")),
        WorldEffect("servo_gain", False, "1", True, False, (0.2, 0.5), _servo_gain),
        WorldEffect("pusher_restitution", False, "1", False, False, (0.3, 0.7), _set("pusher_dampratio", -1.0, 1.0)),
        WorldEffect("stribeck", False, "1", False, False, (0.3, 1.0), _stribeck),
        WorldEffect(
            "friction_gradient", False, "1/m", False, True, (0.5, 3.0), _directional("gradient", "gradient_azimuth")
        ),
        WorldEffect("force_limit", False, "N", False, False, (20.0, 50.0), _set("force_limit")),
    ]
}

LIBRARY = tuple(n for n, e in EFFECTS.items() if e.in_library)
OUTSIDE = tuple(n for n, e in EFFECTS.items() if not e.in_library)
IDENTIFIABLE = tuple(n for n in LIBRARY if EFFECTS[n].identifiable)


def apply_effect(p: WorldPushes, name: str, magnitude: float, azimuth: float = 0.0, extra: dict | None = None) -> None:
    """Set the world's parameters of pushes ``p`` (in place) for effect ``name``."""
    if name not in EFFECTS:
        raise KeyError(f"unknown world effect {name!r} (known: {', '.join(EFFECTS)})")
    EFFECTS[name].apply(p, float(magnitude), float(azimuth), extra or {})


def draw_magnitude(rng: np.random.Generator, name: str, lo: float, hi: float) -> float:
    """A magnitude log-uniform in [lo, hi], of random sign for signed effects."""
    x = float(np.exp(rng.uniform(np.log(lo), np.log(hi))))
    if EFFECTS[name].signed and rng.random() < 0.5:
        x = -x
    return x
