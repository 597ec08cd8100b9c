"""The benchmark's pushes in a second physics engine (Bullet, through pybullet): logs whose contact model is not MuJoCo's.

The diagnostic's push table and the benchmark's own world (:mod:`imply.realworld.world`)
share MuJoCo's contact model: soft constraints (solref/solimp), elliptic friction cones, a
contact margin. A log simulated here is the same experiment in another engine, so a gap
diagnosed on it is partly the gap between two contact models, as a real lab's would be.

The experiment is the scene's (:class:`imply.sim.scene.SceneConfig`): a table plane; a
solid box (its size, mass and friction; inertia of a solid box, from Bullet's own shape);
a pusher carriage of the scene's geometry on a prismatic joint at the box's centre
height, driven by the scene's velocity servo law, force ``kv (u - v)`` clipped to the
force limit, applied as a joint force at every step; it drives the box over the stroke
(the step that would pass the stroke is shortened to end on it), then is commanded to 0
and brakes, and the box slides to rest. As in the world, a push in table direction phi
is simulated along +x, with gravity and the friction laws rotated into the push frame.

What differs from the MuJoCo world (none of it tuned to match the table):

- Bullet's contact model: rigid contacts solved by projected Gauss-Seidel (sequential
  impulses) with Baumgarte error reduction (pybullet's defaults: ERP 0.2, no
  restitution), friction as two independent tangent constraints (a pyramid, the first
  along the sliding velocity) at each of the box's corner contacts; no contact margin
  or soft-constraint time constant. The combined friction of a contact is the product
  of the two bodies' coefficients: the table is given 1, the box its mu, the pusher 0
  (the scene's pusher slides on the box without friction);
- semi-implicit Euler (Bullet's only integrator) on fixed steps per phase;
- pybullet's default linear and angular velocity damping of bodies (0.04) is switched off:
  it is air resistance, not contact, and the nominal world has none;
- every push is simulated in a fresh scene (``resetSimulation``), so no solver warm start
  is carried between pushes and a push's result does not depend on the pushes before it.

Parameters of :data:`imply.realworld.world.PARAMETERS` supported here: ``tilt`` and
``tilt_azimuth`` (gravity rotated in full), ``viscous`` and ``air_density`` (forces on
the box at every step, the world's formulas), ``carriage_mass``, ``servo_kv``,
``force_limit``, ``aniso``/``aniso_axis``, ``stribeck``/``stribeck_speed`` and
``gradient``/``gradient_azimuth`` (the box's friction set at every step from its state at
the start of the step, the world's laws), ``torsional`` and ``rolling`` (Bullet's
spinning and rolling friction, torque = coefficient x normal force at each contact, the
same units as MuJoCo's) and ``height`` (a taller box of the same mass, the pusher at the
canonical height), and the probes' ``stroke`` and ``free`` (the box 10 m beyond the pusher's
reach). Any other parameter at a value other than its nominal one
(``pusher_timeconst``, ``pusher_dampratio``: Bullet's contacts have no solref) raises
:class:`ValueError` naming it; so does a parameter this module does not know.
"""

from __future__ import annotations

import ctypes
import dataclasses
import math
import os
import sys
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from tqdm.auto import tqdm

from imply.options import Config, option
from imply.realworld.stepped import SteppedPush, check_steps, run_push
from imply.realworld.world import WorldPushes, WorldResult, check_track_times
from imply.sim.scene import GRAVITY, SceneConfig

# the parameters this engine implements (any value); every other one must be nominal
SUPPORTED = frozenset(
    {
        "tilt",
        "tilt_azimuth",
        "viscous",
        "air_density",
        "carriage_mass",
        "servo_kv",
        "force_limit",
        "aniso",
        "aniso_axis",
        "stribeck",
        "stribeck_speed",
        "gradient",
        "gradient_azimuth",
        "torsional",
        "rolling",
        "height",
        "stroke",
        "free",
    }
)


@dataclass(frozen=True, kw_only=True)
class BulletStepping(Config):
    """How the Bullet world steps a push (config ``gap.contact_benchmark.bullet``).

    Defaults chosen by measuring convergence (``benchmarks/bench_bullet.py``) on 48 nominal
    pushes (8 boxes, masses 0.2-2 kg, frictions 0.1-0.6, x 6 speeds 0.2-0.9 m/s): halving
    every step moves log d by at most 0.0033 and the stop time by at most 0.7 ms, quartering
    it by at most 0.0046 and 0.9 ms; doubling it moves log d by up to 0.011. Solver
    iterations hardly matter for a box sliding on a plane (10 instead of 50: at most
    0.0007 in log d; 100: nothing).
    """

    config_key: ClassVar[str] = "gap.contact_benchmark.bullet"

    push_step: float = option(
        2.5e-4, doc="s, while pushing (and during the release window)", exclusive_minimum=0, maximum=0.01
    )
    release_window: float = option(0.02, doc="s after the stroke, still at the push step", minimum=0)
    slide_step: float = option(1.0e-3, doc="s, until the box stops", exclusive_minimum=0, maximum=0.01)
    solver_iterations: int = option(50, doc="Bullet's constraint solver iterations per step", minimum=1)
    stop_speed: float = option(
        0.01, doc="m/s in the table plane: the stop time is when the box slows below it", exclusive_minimum=0
    )
    rest_speed: float = option(1.0e-4, doc="m/s in the table plane: below it the push is over", exclusive_minimum=0)
    max_time: float = option(4.0, doc="s a push may take at most", exclusive_minimum=0)

    def __post_init__(self) -> None:
        check_steps(self, "bullet")
        if not (
            isinstance(self.release_window, int | float)
            and math.isfinite(self.release_window)
            and self.release_window >= 0
        ):
            raise ValueError(f"bullet stepping: release_window must be a number >= 0, not {self.release_window!r}")
        if not (isinstance(self.solver_iterations, int) and self.solver_iterations >= 1):
            raise ValueError(
                f"bullet stepping: solver_iterations must be an integer >= 1, not {self.solver_iterations!r}"
            )

    def finer(self, factor: int) -> BulletStepping:
        """The same stepping with every step divided by ``factor`` (for measuring its error)."""
        return dataclasses.replace(self, push_step=self.push_step / factor, slide_step=self.slide_step / factor)


def _pybullet():
    """The pybullet module, imported on first use with its banner sent to stderr.

    pybullet prints "pybullet build time: ..." on C's stdout when imported (flushed at exit
    when stdout is a pipe), which would corrupt any command whose stdout is data.
    """
    if "pybullet" in sys.modules:
        return sys.modules["pybullet"]
    sys.stdout.flush()
    saved = os.dup(1)
    try:
        os.dup2(2, 1)
        import pybullet

        ctypes.CDLL(None).fflush(None)
    finally:
        os.dup2(saved, 1)
        os.close(saved)
    return pybullet


def nominal_parameters(scene: SceneConfig) -> dict[str, float]:
    """The world's parameters at their nominal values (:meth:`WorldPushes.nominal`'s, so new ones come along)."""
    one = WorldPushes.nominal(1.0, 1.0, 1.0, 0.0, scene)
    return {k: float(v[0]) for k, v in one.params.items()}


def check_supported(
    pushes: WorldPushes, scene: SceneConfig, *, supported: frozenset[str] = SUPPORTED, engine: str = "Bullet"
) -> None:
    """Raise ValueError naming every parameter of ``pushes`` that is off its nominal value and not in ``supported``
    (the parameters ``engine``'s world carries)."""
    nominal = nominal_parameters(scene)
    bad = []
    for name, values in pushes.params.items():
        if name in supported:
            continue
        values = np.asarray(values, float)
        if name not in nominal:
            if np.any(values != 0):
                bad.append(f"{name} (unknown to the {engine} world)")
            continue
        if np.any(~np.isclose(values, nominal[name], rtol=0, atol=1e-12)):
            bad.append(name)
    if bad:
        raise ValueError(
            f"the {engine} world does not support the parameter(s) {', '.join(bad)} off their nominal value"
        )


def simulate_bullet(
    pushes: WorldPushes,
    scene: SceneConfig,
    stepping: BulletStepping | None = None,
    *,
    progress: bool = False,
    track_times: np.ndarray | None = None,
) -> WorldResult:
    """Simulate every push of ``pushes`` in Bullet (one push after another on one physics client).

    Returns a :class:`WorldResult` of (n,) arrays: travel along and across the push (m),
    stop time (s), ok (finite, stopped before ``max_time``, not tipped, moved forward), the
    number of steps taken, the stroke time (s), the servo's mean force over the second half
    of the stroke (N) and, at ``track_times``, the box's track.
    """
    track_times = check_track_times(track_times)
    stepping = stepping or BulletStepping()
    check_supported(pushes, scene)
    pybullet = _pybullet()
    client = pybullet.connect(pybullet.DIRECT)
    try:
        return collect_pushes(
            pushes,
            scene,
            lambda **kw: _push(client, scene, stepping, **kw),
            supported=SUPPORTED,
            desc="bullet pushes",
            progress=progress,
            track_times=track_times,
        )
    finally:
        pybullet.disconnect(client)


def collect_pushes(
    pushes: WorldPushes,
    scene: SceneConfig,
    one_push,
    *,
    supported: frozenset[str],
    desc: str,
    progress: bool,
    track_times: np.ndarray | None,
) -> WorldResult:
    """Run ``one_push(speed=, mass=, friction=, direction=, prm=, track_times=)`` -> :class:`SteppedPush` for every
    push of ``pushes`` in turn (``prm``: the parameters in ``supported``), gathered into a :class:`WorldResult`."""
    nominal = nominal_parameters(scene)
    n = pushes.n
    params = {
        k: np.broadcast_to(np.asarray(pushes.params.get(k, v), float), (n,))
        for k, v in nominal.items()
        if k in supported
    }
    fields = ("displacement", "lateral", "stop_time", "stroke_time", "drive_force")
    out = {f: np.zeros(n) for f in fields}
    ok = np.zeros(n, bool)
    steps = np.zeros(n, np.int64)
    track = None if track_times is None else np.zeros((n, track_times.size, 3))
    for i in tqdm(range(n), desc=desc, unit="push", disable=not progress, leave=False):
        one = one_push(
            speed=float(pushes.speed[i]),
            mass=float(pushes.mass[i]),
            friction=float(pushes.friction[i]),
            direction=float(pushes.direction[i]),
            prm={k: float(v[i]) for k, v in params.items()},
            track_times=track_times,
        )
        for f in fields:
            out[f][i] = getattr(one, f)
        ok[i], steps[i] = one.ok, one.steps
        if track is not None:
            track[i] = one.track
    return WorldResult(
        out["displacement"], out["lateral"], out["stop_time"], ok, steps, out["stroke_time"], track, out["drive_force"]
    )


def _build(client: int, scene: SceneConfig, *, mass: float, prm: dict[str, float]) -> tuple[int, int]:
    """A fresh scene on ``client``: table, box, pusher carriage; returns (box, pusher) body ids."""
    pybullet = _pybullet()
    pybullet.resetSimulation(physicsClientId=client)
    hx, hy, hz = (float(x) for x in scene.box_half_extents)
    bz = hz * (1.0 + prm["height"])  # a taller box; the pusher stays at the rig's height
    away = 10.0 if prm["free"] else 0.0  # a free stroke: the box waits beyond the pusher's reach
    table_shape = pybullet.createCollisionShape(pybullet.GEOM_PLANE, physicsClientId=client)
    table = pybullet.createMultiBody(0.0, table_shape, physicsClientId=client)
    box_shape = pybullet.createCollisionShape(pybullet.GEOM_BOX, halfExtents=[hx, hy, bz], physicsClientId=client)
    box = pybullet.createMultiBody(mass, box_shape, basePosition=[away, 0.0, bz], physicsClientId=client)
    # the scene's pusher: half-extents (0.01, 0.8 hy, 0.01), its face 0.1 mm behind the box
    pusher_half = 0.01
    pusher_shape = pybullet.createCollisionShape(
        pybullet.GEOM_BOX, halfExtents=[pusher_half, 0.8 * hy, 0.01], physicsClientId=client
    )
    pusher = pybullet.createMultiBody(
        baseMass=0.0,
        baseCollisionShapeIndex=-1,
        basePosition=[-hx - pusher_half - 1e-4, 0.0, hz],
        linkMasses=[prm["carriage_mass"]],
        linkCollisionShapeIndices=[pusher_shape],
        linkVisualShapeIndices=[-1],
        linkPositions=[[0.0, 0.0, 0.0]],
        linkOrientations=[[0.0, 0.0, 0.0, 1.0]],
        linkInertialFramePositions=[[0.0, 0.0, 0.0]],
        linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]],
        linkParentIndices=[0],
        linkJointTypes=[pybullet.JOINT_PRISMATIC],
        linkJointAxis=[[1.0, 0.0, 0.0]],
        physicsClientId=client,
    )
    # the carriage runs above the table without touching it (the scene's contype/conaffinity)
    pybullet.setCollisionFilterPair(pusher, table, 0, -1, 0, physicsClientId=client)
    pybullet.changeDynamics(table, -1, lateralFriction=1.0, physicsClientId=client)
    pybullet.changeDynamics(
        box,
        -1,
        lateralFriction=1.0,
        spinningFriction=prm["torsional"],
        rollingFriction=prm["rolling"],
        linearDamping=0.0,
        angularDamping=0.0,
        physicsClientId=client,
    )
    pybullet.changeDynamics(
        pusher,
        0,
        lateralFriction=0.0,
        linearDamping=0.0,
        angularDamping=0.0,
        jointDamping=0.0,
        physicsClientId=client,
    )
    pybullet.changeDynamics(pusher, -1, linearDamping=0.0, angularDamping=0.0, physicsClientId=client)
    # the joint's built-in velocity motor off: the servo law is applied as a joint force
    pybullet.setJointMotorControl2(pusher, 0, pybullet.VELOCITY_CONTROL, force=0.0, physicsClientId=client)
    return box, pusher


class _BulletRig:
    """The rig's calls (:class:`imply.realworld.stepped.EngineRig`) on a Bullet scene."""

    def __init__(self, client: int, box: int, pusher: int, step: float) -> None:
        self.pybullet = _pybullet()
        self.client, self.box, self.pusher = client, box, pusher
        self.pybullet.setPhysicsEngineParameter(fixedTimeStep=step, physicsClientId=client)

    def pusher_state(self) -> tuple[float, float]:
        return self.pybullet.getJointState(self.pusher, 0, physicsClientId=self.client)[:2]

    def box_pose(self):
        return self.pybullet.getBasePositionAndOrientation(self.box, physicsClientId=self.client)

    def box_velocity(self):
        return self.pybullet.getBaseVelocity(self.box, physicsClientId=self.client)[0]

    def rotation(self, quat) -> np.ndarray:
        return np.array(self.pybullet.getMatrixFromQuaternion(quat)).reshape(3, 3)

    def push_box(self, force, position) -> None:
        self.pybullet.applyExternalForce(
            self.box, -1, force.tolist(), position, self.pybullet.WORLD_FRAME, physicsClientId=self.client
        )

    def set_box_friction(self, friction: float) -> None:
        self.pybullet.changeDynamics(self.box, -1, lateralFriction=friction, physicsClientId=self.client)

    def drive(self, force: float) -> None:
        self.pybullet.setJointMotorControl2(
            self.pusher, 0, self.pybullet.TORQUE_CONTROL, force=force, physicsClientId=self.client
        )

    def set_step(self, step: float) -> None:
        self.pybullet.setPhysicsEngineParameter(fixedTimeStep=step, physicsClientId=self.client)

    def step(self) -> None:
        self.pybullet.stepSimulation(physicsClientId=self.client)


def _push(
    client: int,
    scene: SceneConfig,
    st: BulletStepping,
    *,
    speed: float,
    mass: float,
    friction: float,
    direction: float,
    prm: dict[str, float],
    track_times: np.ndarray | None = None,
) -> SteppedPush:
    """One push, and the box's track at ``track_times`` where given."""
    pybullet = _pybullet()
    box, pusher = _build(client, scene, mass=mass, prm=prm)
    # gravity of a table tilted by `tilt` downhill toward table azimuth psi, in the push frame
    rel = prm["tilt_azimuth"] - direction
    tilt = prm["tilt"]
    g = (
        float(np.linalg.norm([float(x) for x in scene.option["gravity"].split()]))
        if "gravity" in scene.option
        else GRAVITY
    )
    gravity = (g * math.sin(tilt) * math.cos(rel), g * math.sin(tilt) * math.sin(rel), -g * math.cos(tilt))
    pybullet.setGravity(*gravity, physicsClientId=client)
    pybullet.setPhysicsEngineParameter(numSubSteps=0, numSolverIterations=st.solver_iterations, physicsClientId=client)
    hx, hy, hz = (float(x) for x in scene.box_half_extents)
    bz = hz * (1.0 + prm["height"])
    area = (4.0 * hy * bz, 4.0 * hx * bz, 4.0 * hx * hy)  # cross-sections per box axis, for air drag
    rig = _BulletRig(client, box, pusher, st.push_step)
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
