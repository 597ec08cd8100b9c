"""The push scene as MJCF: a table, a box, and a velocity-servoed pusher.

Why this mechanism: a free elastic strike gives log d = 2 log v + c(m, mu), which
cannot tell mass from friction. Here a pusher carriage, driven by a velocity servo
(force = kv (v - u), force-limited), starts against the box and drives it over a
fixed stroke, then brakes; the box slides on. While pushing, the box's speed lags the
command by about mu m g / kv and approaches it with time constant (m + m_p) / kv,
so mass shapes the release speed in a speed-dependent way, while friction sets the
slide after release. Mass and friction therefore act differently across speeds.

Numerical choices (measured on the full table range): elliptic friction cones; the
semi-implicit ``Euler`` integrator with a fine step while pushing (see
:mod:`imply.sim.pushes` for why, and ``imply table check`` for the measured error); a
contact margin on the box so its corner contacts do not flicker while sliding; the
pusher strikes at the box's centre height so the box slides rather than tips; inertia
scales with mass (MJCF ``mass=`` on the geom).

The MJCF carries everything a push needs (``<custom>`` numerics ``stroke``,
``settle_speed``, ``max_time``, ``push_substeps``, ``release_window``, ``slide_steps``
and ``slow_push_speed``), so a
user-edited file is simulated exactly as the built-in scene is. A scene may also carry
``command_offset``: m/s added to every commanded pusher speed (how a corrected scene,
:mod:`imply.sim.correction`, states a pusher that runs at another speed than it is told).
Names the simulator relies on: body and geom ``box``, joint ``push``, actuator ``servo``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, ClassVar

import mujoco
import numpy as np

from imply.options import Config, option

# a corrected scene's command mapping (imply.sim.correction): m/s the simulator adds to every commanded pusher speed
COMMAND_OFFSET = "command_offset"
# m/s^2: MuJoCo's default gravity, the scene's unless its extra options name another; a pull test's reading is its
# force over the box's weight m times this
GRAVITY = 9.81


@dataclass(frozen=True, kw_only=True)
class SceneConfig(Config):
    """Physical and numerical settings of the push scene (config key ``scene``)."""

    config_key: ClassVar[str] = "scene"

    timestep: float = option(
        0.001,
        doc="s, while the box slides; pushing uses timestep / push_substeps",
        exclusive_minimum=0,
        maximum=0.01,
    )
    push_substeps: int = option(8, doc="substeps per timestep while pushing", minimum=1)
    release_window: float = option(0.005, doc="s after the stroke still at the fine step", minimum=0)
    slide_steps: int = option(
        100, doc="a slide shorter than slide_steps x timestep uses a finer step (0: never)", minimum=0
    )
    slow_push_speed: float = option(0.35, doc="m/s; slower pushes take twice the push substeps", minimum=0)
    box_half_extents: tuple[float, float, float] = option(
        (0.05, 0.05, 0.03), doc="the canonical box's half-extents (m)", items={"exclusive_minimum": 0}
    )
    mass: float = option(0.5, doc="the box's mass when a push names none (kg)", exclusive_minimum=0)
    friction: float = option(0.3, doc="the box's friction when a push names none", exclusive_minimum=0)
    pusher_mass: float = option(0.2, doc="kg", exclusive_minimum=0)
    pusher_kv: float = option(80.0, doc="the pusher's velocity servo gain (N s/m)", exclusive_minimum=0)
    pusher_force_limit: float = option(100.0, doc="N", exclusive_minimum=0)
    stroke: float = option(0.01, doc="m the pusher travels", exclusive_minimum=0)
    contact_margin: float = option(0.002, doc="m", minimum=0)
    settle_speed: float = option(1.0e-4, doc="m/s below which the box is at rest", exclusive_minimum=0)
    max_time: float = option(4.0, doc="s a push may take at most", exclusive_minimum=0)
    option: dict[str, str] = option(
        {}, doc="extra MJCF <option> attributes, e.g. {gravity: '0 0 -9.81'} (MuJoCo checks their names)"
    )

    def __post_init__(self) -> None:
        positive = (
            "timestep",
            "mass",
            "friction",
            "pusher_mass",
            "pusher_kv",
            "pusher_force_limit",
            "stroke",
            "settle_speed",
            "max_time",
        )
        for name in positive:
            value = getattr(self, name)
            if not (
                isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value) and value > 0
            ):
                raise ValueError(f"scene option {name} must be a positive number, not {value!r}")
        for name in ("contact_margin", "release_window", "slow_push_speed"):
            value = getattr(self, name)
            if not (
                isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value) and value >= 0
            ):
                raise ValueError(f"scene option {name} must be a number >= 0, not {value!r}")
        for name, least in (("push_substeps", 1), ("slide_steps", 0)):
            value = getattr(self, name)
            if not (isinstance(value, int) and not isinstance(value, bool) and value >= least):
                raise ValueError(f"scene option {name} must be an integer >= {least}, not {value!r}")
        he = self.box_half_extents
        if len(he) != 3 or not all(isinstance(x, int | float) and math.isfinite(x) and x > 0 for x in he):
            raise ValueError(f"scene option box_half_extents must be three positive numbers, not {list(he)!r}")
        fine = self.timestep / self.push_substeps
        if self.max_time / fine > 1e7:
            raise ValueError(
                f"scene timestep {self.timestep!r} with push_substeps {self.push_substeps} would take "
                f"{self.max_time / fine:.3g} substeps per push (max_time {self.max_time:g} s); at most 1e7 are allowed"
            )


def build_xml(
    scene: SceneConfig | None = None,
    half_extents: tuple[float, float, float] | None = None,
    mass: float | None = None,
    friction: float | None = None,
) -> str:
    """MJCF text of the push scene for one box (defaults from ``scene``)."""
    s = scene or SceneConfig()
    hx, hy, hz = (float(x) for x in (half_extents if half_extents is not None else s.box_half_extents))
    m = float(s.mass if mass is None else mass)
    mu = float(s.friction if friction is None else friction)
    # the pusher face starts 0.1 mm behind the box, at the box's centre height
    pusher_half = 0.01
    pusher_x = -hx - pusher_half - 1e-4
    # Euler unless the scene's extra options name another integrator (see imply.sim.pushes)
    option = {"integrator": "Euler", **s.option}
    opt = " ".join(f'{k}="{v}"' for k, v in sorted(option.items()))
    return f"""<mujoco model="imply_push">
  <compiler angle="radian"/>
  <option timestep="{s.timestep!r}" cone="elliptic" {opt}/>
  <visual><quality shadowsize="0" offsamples="0"/><global offwidth="640" offheight="480"/></visual>
  <custom>
    <numeric name="stroke" data="{s.stroke!r}"/>
    <numeric name="settle_speed" data="{s.settle_speed!r}"/>
    <numeric name="max_time" data="{s.max_time!r}"/>
    <numeric name="push_substeps" data="{s.push_substeps!r}"/>
    <numeric name="release_window" data="{s.release_window!r}"/>
    <numeric name="slide_steps" data="{s.slide_steps!r}"/>
    <numeric name="slow_push_speed" data="{s.slow_push_speed!r}"/>
  </custom>
  <asset>
    <texture name="grid" type="2d" builtin="checker" rgb1="0.55 0.55 0.55" rgb2="0.45 0.45 0.45" width="64" height="64"/>
    <material name="table" texture="grid" texrepeat="8 8"/>
  </asset>
  <worldbody>
    <light name="top" pos="0 0 2" dir="0 0 -1" directional="true"/>
    <geom name="table" type="plane" size="3 3 0.1" material="table" friction="0.01 0 0" contype="1" conaffinity="1"/>
    <body name="box" pos="0 0 {hz!r}">
      <freejoint name="box"/>
      <geom name="box" type="box" size="{hx!r} {hy!r} {hz!r}" mass="{m!r}" friction="{mu!r} 0.005 0.0001"
            priority="1" margin="{s.contact_margin!r}" contype="1" conaffinity="3" rgba="0.85 0.35 0.2 1"/>
    </body>
    <body name="pusher" pos="{pusher_x!r} 0 {hz!r}">
      <joint name="push" type="slide" axis="1 0 0" range="0 {s.stroke + 0.03!r}" limited="true"/>
      <geom name="pusher" type="box" size="{pusher_half} {0.8 * hy!r} 0.01" mass="{s.pusher_mass!r}"
            contype="2" conaffinity="0" friction="0 0 0" priority="2" rgba="0.2 0.3 0.8 1"/>
    </body>
    <camera name="top" pos="0.25 0 1.1" xyaxes="1 0 0 0 1 0"/>
  </worldbody>
  <actuator>
    <velocity name="servo" joint="push" kv="{s.pusher_kv!r}" forcelimited="true"
              forcerange="-{s.pusher_force_limit!r} {s.pusher_force_limit!r}"/>
  </actuator>
</mujoco>
"""


def build_model(scene: SceneConfig | None = None, **kwargs: Any) -> mujoco.MjModel:
    """Compiled MjModel of :func:`build_xml`."""
    return mujoco.MjModel.from_xml_string(build_xml(scene, **kwargs))


def model_numeric(model: mujoco.MjModel, name: str, default: float | None = None) -> float:
    """A ``<custom><numeric>`` value of a push model, or ``default`` if absent."""
    try:
        return float(np.asarray(model.numeric(name).data)[0])
    except KeyError:
        if default is None:
            raise ValueError(f"push model has no <numeric name='{name}'> in <custom>") from None
        return default
