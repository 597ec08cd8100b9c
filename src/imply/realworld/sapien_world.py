"""The benchmark's pushes in a third physics engine (NVIDIA PhysX, through SAPIEN, on the CPU): never used to choose.

Neither the push table, the diagnostic's settings nor any benchmark threshold was chosen on
this engine's logs: the gap benchmark's development set holds MuJoCo contact variants and
Bullet, and this world enters only its sealed set, as a robot whose contact nobody tuned
would.

The experiment is the scene's (:class:`imply.sim.scene.SceneConfig`), stepped by the
rig's protocol (:func:`imply.realworld.stepped.run_push`): a static table slab; a solid box
(its size and mass, PhysX's inertia of a solid box); a pusher carriage of the scene's
geometry and mass at the box's centre height, a free body whose motion is locked to the
push axis (a rail) with gravity off, driven by the scene's velocity servo law applied as a
force at every step. A push in table direction phi is simulated along +x, with gravity
and the friction laws rotated into the push frame. Every push runs in a fresh scene.

What differs from the MuJoCo world (none of it tuned to match the table):

- PhysX's contact model: rigid contacts with a contact offset (PhysX's 1 cm default shell
  inside which contacts are generated early), the temporal Gauss-Seidel solver (SAPIEN's
  default), friction patches with static and dynamic coefficients (both set to the box's
  mu). PhysX combines two materials' friction by their average, so the table's and the
  box's material are one, set to the box's mu; the pusher's face has friction 0, which
  combines with the box's to mu / 2 (MuJoCo's pusher slides without friction): the
  engine's own pusher contact, left as it is;
- PhysX puts slow bodies to sleep (its default threshold), which may end a slide early;
- bodies' angular damping (SAPIEN's default 0.05) is switched off, as Bullet's damping is:
  it is air resistance, not contact.

Parameters of :data:`imply.realworld.world.PARAMETERS` supported here: ``tilt`` and
``tilt_azimuth``, ``viscous`` and ``air_density``, ``carriage_mass``, ``servo_kv``,
``force_limit``, ``aniso``/``aniso_axis``, ``stribeck``/``stribeck_speed``,
``gradient``/``gradient_azimuth`` (the world's laws, by the rig's protocol), ``height``, and
the probes' ``stroke`` and ``free``. Not supported (:class:`ValueError` naming them when off
their nominal value): the pusher contact's ``pusher_timeconst``/``pusher_dampratio``
(PhysX has no soft-constraint time constant), ``torsional`` and ``rolling`` (PhysX has no
torsional or rolling friction coefficients on a box), and the MuJoCo contact variants.
The library effects this world carries are :data:`imply.realworld.contact.SAPIEN_EFFECTS`.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from imply.options import Config, option
from imply.realworld.bullet import SUPPORTED as BULLET_SUPPORTED
from imply.realworld.bullet import check_supported, collect_pushes
from imply.realworld.stepped import SteppedPush, check_steps, run_push
from imply.realworld.world import WorldPushes, WorldResult, check_track_times
from imply.sim.scene import GRAVITY, SceneConfig

# the parameters this engine implements (any value); every other one must be nominal
# (Bullet's, less the torsional and rolling friction PhysX has no coefficients for)
SUPPORTED = BULLET_SUPPORTED - {"torsional", "rolling"}
# collision groups: the table meets the box, the pusher meets the box, the carriage runs above the table
_TABLE, _BOX, _PUSHER = [1, 1, 0, 0], [3, 3, 0, 0], [2, 2, 0, 0]


@dataclass(frozen=True, kw_only=True)
class SapienStepping(Config):
    """How the SAPIEN (PhysX) world steps a push (config ``gap.lab_benchmark.sapien``).

    The same steps as the Bullet world's; PhysX's solver iterations per body."""

    config_key: ClassVar[str] = "gap.lab_benchmark.sapien"

    push_step: float = option(
        2.5e-4, doc="s, while pushing (and during the release window)", exclusive_minimum=0, maximum=0.01
    )
    release_window: float = option(0.02, doc="s after the stroke, still at the push step", minimum=0)
    slide_step: float = option(1.0e-3, doc="s, until the box stops", exclusive_minimum=0, maximum=0.01)
    position_iterations: int = option(10, doc="PhysX's position iterations per step (the box's)", minimum=1)
    stop_speed: float = option(
        0.01, doc="m/s in the table plane: the stop time is when the box slows below it", exclusive_minimum=0
    )
    rest_speed: float = option(1.0e-4, doc="m/s in the table plane: below it the push is over", exclusive_minimum=0)
    max_time: float = option(4.0, doc="s a push may take at most", exclusive_minimum=0)

    def __post_init__(self) -> None:
        check_steps(self, "sapien")

    def finer(self, factor: int) -> SapienStepping:
        """The same stepping with every step divided by ``factor`` (for measuring its error)."""
        return dataclasses.replace(self, push_step=self.push_step / factor, slide_step=self.slide_step / factor)


def _sapien():
    """The sapien module (imported on first use: only this world's logs need it; its renderer's warnings muted)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import sapien
    return sapien


def simulate_sapien(
    pushes: WorldPushes,
    scene: SceneConfig,
    stepping: SapienStepping | None = None,
    *,
    progress: bool = False,
    track_times: np.ndarray | None = None,
) -> WorldResult:
    """Simulate every push of ``pushes`` in PhysX, each in a fresh scene.

    Returns a :class:`WorldResult` of (n,) arrays, as :func:`imply.realworld.bullet.simulate_bullet` does.
    """
    track_times = check_track_times(track_times)
    stepping = stepping or SapienStepping()
    check_supported(pushes, scene, supported=SUPPORTED, engine="SAPIEN")
    return collect_pushes(
        pushes,
        scene,
        lambda **kw: _push(scene, stepping, **kw),
        supported=SUPPORTED,
        desc="sapien pushes",
        progress=progress,
        track_times=track_times,
    )


class _SapienRig:
    """The rig's calls (:class:`imply.realworld.stepped.EngineRig`) on a SAPIEN scene."""

    def __init__(self, scene, material, box, pusher) -> None:
        self.scene, self.material, self.box, self.pusher = scene, material, box, pusher
        self.x0 = float(pusher.entity_pose.p[0])

    def pusher_state(self) -> tuple[float, float]:
        return float(self.pusher.entity_pose.p[0]) - self.x0, float(self.pusher.linear_velocity[0])

    def box_pose(self) -> tuple[np.ndarray, np.ndarray]:
        pose = self.box.entity_pose
        w, x, y, z = (float(c) for c in pose.q)
        return np.asarray(pose.p, float), np.array([x, y, z, w])

    def box_velocity(self) -> np.ndarray:
        return np.asarray(self.box.linear_velocity, float)

    def rotation(self, quat: np.ndarray) -> np.ndarray:
        x, y, z, w = quat
        return np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )

    def push_box(self, force: np.ndarray, position: np.ndarray) -> None:
        self.box.add_force_at_point(np.asarray(force, np.float32), np.asarray(position, np.float32))

    def set_box_friction(self, friction: float) -> None:
        self.material.set_static_friction(friction)
        self.material.set_dynamic_friction(friction)

    def drive(self, force: float) -> None:
        self.pusher.add_force_at_point(np.array([force, 0.0, 0.0], np.float32), np.asarray(self.pusher.entity_pose.p))

    def set_step(self, step: float) -> None:
        self.scene.set_timestep(step)

    def step(self) -> None:
        self.scene.step()


def _push(
    scene: SceneConfig,
    st: SapienStepping,
    *,
    speed: float,
    mass: float,
    friction: float,
    direction: float,
    prm: dict[str, float],
    track_times: np.ndarray | None = None,
) -> SteppedPush:
    """One push in a fresh PhysX scene, and the box's track at ``track_times`` where given."""
    sapien = _sapien()
    px = sapien.physx
    rel = prm["tilt_azimuth"] - direction
    tilt = prm["tilt"]
    g = (
        float(np.linalg.norm([float(x) for x in scene.option["gravity"].split()]))
        if "gravity" in scene.option
        else GRAVITY
    )
    config = px.PhysxSceneConfig()
    config.gravity = np.array(
        [g * math.sin(tilt) * math.cos(rel), g * math.sin(tilt) * math.sin(rel), -g * math.cos(tilt)], np.float32
    )
    px.set_scene_config(config)  # read when the system is made: a tilted table's gravity
    world = sapien.Scene([px.PhysxCpuSystem()])
    world.set_timestep(st.push_step)
    hx, hy, hz = (float(x) for x in scene.box_half_extents)
    bz = hz * (1.0 + prm["height"])  # a taller box; the pusher stays at the rig's height
    away = 10.0 if prm["free"] else 0.0  # a free stroke: the box waits beyond the pusher's reach
    contact = px.PhysxMaterial(friction, friction, 0.0)  # the table's and the box's: PhysX averages the two
    builder = world.create_actor_builder()
    builder.add_box_collision(pose=sapien.Pose([0.0, 0.0, -0.05]), half_size=[12.0, 2.0, 0.05], material=contact)
    table = builder.build_static(name="table")
    builder = world.create_actor_builder()
    builder.add_box_collision(half_size=[hx, hy, bz], material=contact, density=mass / (8.0 * hx * hy * bz))
    box_entity = builder.build(name="box")
    box_entity.set_pose(sapien.Pose([away, 0.0, bz]))
    pusher_half = 0.01
    builder = world.create_actor_builder()
    builder.add_box_collision(
        half_size=[pusher_half, 0.8 * hy, 0.01],
        material=px.PhysxMaterial(0.0, 0.0, 0.0),
        density=prm["carriage_mass"] / (8.0 * pusher_half * 0.8 * hy * 0.01),
    )
    pusher_entity = builder.build(name="pusher")
    pusher_entity.set_pose(sapien.Pose([-hx - pusher_half - 1e-4, 0.0, hz]))
    for entity, groups in ((table, _TABLE), (box_entity, _BOX), (pusher_entity, _PUSHER)):
        for comp in entity.components:
            for shape in getattr(comp, "collision_shapes", []):
                shape.set_collision_groups(groups)
    box = box_entity.find_component_by_type(px.PhysxRigidDynamicComponent)
    box.set_angular_damping(0.0)
    box.set_linear_damping(0.0)
    box.set_solver_position_iterations(st.position_iterations)
    pusher = pusher_entity.find_component_by_type(px.PhysxRigidDynamicComponent)
    pusher.set_locked_motion_axes([False, True, True, True, True, True])  # a rail along the push
    pusher.set_disable_gravity(True)
    pusher.set_angular_damping(0.0)
    pusher.set_linear_damping(0.0)
    area = (4.0 * hy * bz, 4.0 * hx * bz, 4.0 * hx * hy)  # cross-sections per box axis, for air drag
    rig = _SapienRig(world, contact, box, pusher)
    return run_push(
        rig,
        st,
        speed=speed,
        friction=friction,
        direction=direction,
        prm=prm,
        stroke=prm["stroke"],
        area=area,
        track_times=track_times,
    )
