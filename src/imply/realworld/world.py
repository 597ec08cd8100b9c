"""The benchmark's world: pushes of the project's scene, stepped to convergence on a code path of its own.

The scene is the project's (:func:`imply.sim.scene.build_xml`: table, box, velocity-
servoed pusher carriage) and a push is the same experiment: the carriage drives the box
over the stroke, brakes, and the box slides to rest. How it is stepped is not the
table's (:mod:`imply.sim.pushes`):

- MuJoCo's ``RK4`` integrator instead of semi-implicit ``Euler``;
- uniform steps per phase: ``push_step`` while pushing (``slow_push_step`` below
  ``slow_speed``, whose pushes last longer and rock the box more), the same step for a
  ``release_window`` after the stroke, then ``slide_step`` until the box stops; no
  shortened slide steps and no travel correction (RK4 has no first-order travel error to
  correct). The stroke ends on the stroke: the step that would pass it is shortened. A
  box-table contact stiffer than the scene's (``table_timeconst`` below 1) has every step
  shortened by that factor: the nominal steps leave a stiff, underdamped contact up to
  about 0.02 in log d from its converged slide;
- the stop time is when the box's speed in the table plane falls below ``stop_speed``
  (interpolated within the step); the push goes on until it falls below ``rest_speed``.
  MuJoCo's soft contacts end a slide in an exponential tail of a few milliseconds, in
  which a lower threshold's crossing moves with every numerical detail.

:mod:`imply.realworld.accuracy` measures what these choices cost against the same world
stepped four times finer and against :mod:`imply.sim.reference`.

Every deviation from the nominal world is a per-push parameter of :class:`WorldPushes`
(nominal values: none), injected here through its own mechanism:

- tilt: gravity rotated in full, including its component across the push;
- viscous friction ``-b v`` and air drag (the inertia-box formula of MuJoCo's fluid
  model, ``-rho/2 * A_i |v_i| v_i`` per body axis, A_i the box's cross-section) as
  external forces on the box, evaluated at every step;
- friction laws evaluated at every step from the box's state: anisotropic
  (``1 + a cos 2(theta - axis)``, theta the sliding direction on the table), Stribeck
  (``1 + s exp(-(|v| / v_s)^2)``) and friction that varies along the table
  (``1 + k * travel toward azimuth``);
- the carriage (its mass, the servo's gain and force limit, the commanded speed's
  actual value) and the pusher's contact (solref time constant and damping ratio);
- torsional and rolling friction (contact dimension 4 or 6) and a box height
  different from the canonical one, which change the model's structure: those pushes
  run in a batch of their own.

and the world's contact model (:mod:`imply.realworld.contact`; nominal: MuJoCo's contact,
exactly as the table has it): the box-table contact's solref time constant and damping
ratio, friction laws of the sliding speed (velocity-dependent, ``1 + k (|v| - v_ref)``,
and regularised, ``r + (1 - r) tanh(|v| / v_eps)``), and the pusher-box contact's
impedance and friction.

Forces and friction laws are evaluated at the state predicted for the middle of the
coming step (the last step's acceleration carried half a step on), since MuJoCo holds
them constant over a step.
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass, field
from typing import ClassVar

import mujoco
import numpy as np
from mujoco import batch as mjbatch
from tqdm.auto import tqdm

from imply.options import Config, option
from imply.sim.scene import SceneConfig, build_xml
from imply.sim.track import yaw_of

log = logging.getLogger("imply.realworld")


@dataclass(frozen=True, kw_only=True)
class WorldStepping(Config):
    """How the world steps a push (config ``gap.benchmark.stepping``)."""

    config_key: ClassVar[str] = "gap.benchmark.stepping"

    integrator: str = option("RK4", doc="MuJoCo integrator", choices=("RK4", "Euler", "implicit", "implicitfast"))
    push_step: float = option(
        2.5e-4, doc="s, while pushing (and during the release window)", exclusive_minimum=0, maximum=0.01
    )
    slow_push_step: float = option(
        1.25e-4, doc="s, for pushes commanded below slow_speed", exclusive_minimum=0, maximum=0.01
    )
    slow_speed: float = option(0.35, doc="m/s", minimum=0)
    release_window: float = option(0.02, doc="s after the stroke, still at the push step", minimum=0)
    slide_step: float = option(1.0e-3, doc="s, until the box stops", exclusive_minimum=0, maximum=0.01)
    stop_speed: float = option(
        0.01, doc="m/s in the table plane: the stop time is when the box slows below it", exclusive_minimum=0
    )
    rest_speed: float = option(1.0e-4, doc="m/s in the table plane: below it the push is over", exclusive_minimum=0)
    max_time: float = option(4.0, doc="s a push may take at most", exclusive_minimum=0)
    contact_steps: bool = option(
        True,
        doc="shorten every step of a push whose box-table contact is stiffer than the scene's by its time constant's "
        "factor (false: the nominal steps, which miss a stiff underdamped contact's slide by about 0.02 in log d)",
    )

    def __post_init__(self) -> None:
        if self.integrator not in ("RK4", "Euler", "implicit", "implicitfast"):
            raise ValueError(f"world stepping: unknown integrator {self.integrator!r}")
        for name in ("push_step", "slow_push_step", "slide_step", "stop_speed", "rest_speed", "max_time"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and np.isfinite(value) and value > 0):
                raise ValueError(f"world stepping: {name} must be a positive number, not {value!r}")
        for name in ("slow_speed", "release_window"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and np.isfinite(value) and value >= 0):
                raise ValueError(f"world stepping: {name} must be a number >= 0, not {value!r}")
        if self.max_time / min(self.push_step, self.slow_push_step) > 1e7:
            raise ValueError("world stepping: a push could take more than 1e7 steps; raise the steps")

    def finer(self, factor: int) -> WorldStepping:
        """The same stepping with every step divided by ``factor`` (for measuring its error)."""
        return dataclasses.replace(
            self,
            push_step=self.push_step / factor,
            slow_push_step=self.slow_push_step / factor,
            slide_step=self.slide_step / factor,
        )


# per-push parameters of the world and their nominal values (None: from the scene)
PARAMETERS: dict[str, float | None] = {
    "tilt": 0.0,  # rad, slope of the table
    "tilt_azimuth": 0.0,  # rad, downhill direction in the table frame
    "viscous": 0.0,  # N s/m, force -b v on the box
    "air_density": 0.0,  # kg/m^3, quadratic drag on the box
    "pusher_timeconst": 0.0,  # s added to the pusher contact's solref time constant
    "pusher_dampratio": 1.0,  # the pusher contact's damping ratio (below 1: it bounces)
    "carriage_mass": None,  # kg (scene.pusher_mass)
    "servo_kv": None,  # N s/m (scene.pusher_kv)
    "force_limit": None,  # N (scene.pusher_force_limit)
    "aniso": 0.0,  # friction anisotropy a
    "aniso_axis": 0.0,  # rad, table-frame axis of the larger friction (a > 0)
    "stribeck": 0.0,  # s: friction at rest is mu (1 + s)
    "stribeck_speed": 0.05,  # m/s, v_s
    "gradient": 0.0,  # 1/m: friction grows by this fraction per metre toward gradient_azimuth
    "gradient_azimuth": 0.0,  # rad
    "torsional": 0.0,  # m, torsional friction coefficient (contact dimension 4)
    "rolling": 0.0,  # m, rolling friction coefficient (contact dimension 6)
    "height": 0.0,  # fraction by which the box is taller than the canonical one
    # the rig's probes (imply.realworld.probes): a longer stroke (a pull test), and a stroke with no box
    "stroke": None,  # m the pusher travels (scene.stroke)
    "free": 0.0,  # 1: the box is moved far away, and the pusher strokes free (a free stroke)
    # the contact model (imply.realworld.contact): ways the world's contact differs from the table's
    "table_timeconst": 1.0,  # factor on the box-table contact's solref time constant (below 1: stiffer)
    "table_dampratio": 1.0,  # factor on the box-table contact's damping ratio
    "friction_slope": 0.0,  # m^-1 s: Coulomb friction mu (1 + k (|v| - v_ref)) for sliding speed |v|
    "friction_slope_speed": 0.0,  # m/s, v_ref of friction_slope
    "friction_regularisation": 0.0,  # m/s, v_eps: friction mu (r + (1 - r) tanh(|v| / v_eps)) (zero: plain Coulomb)
    "friction_rest_share": 0.5,  # r, the share of friction left at zero slip under friction_regularisation
    "pusher_friction": 0.0,  # friction coefficient of the pusher's face on the box
    "pusher_impedance": 0.0,  # lowered from the pusher contact's solimp dmin and dmax (0: MuJoCo's 0.9, 0.95)
}
# the parameters through which a push's table direction enters its simulation: every world (MuJoCo's here, and the
# stepped engines' of imply.realworld.stepped) pushes along its own +x, and turns only gravity (a tilt) and the
# friction laws that depend on where on the table the box slides (anisotropy, a gradient) by the direction
DIRECTIONAL_PARAMETERS = ("tilt", "aniso", "gradient")


@dataclass(frozen=True)
class WorldPushes:
    """n pushes: commanded (actual) servo speed, box mass, friction, direction, and the world's parameters."""

    speed: np.ndarray
    mass: np.ndarray
    friction: np.ndarray
    direction: np.ndarray
    params: dict[str, np.ndarray] = field(default_factory=dict)

    @classmethod
    def nominal(cls, speed, mass, friction, direction, scene: SceneConfig) -> WorldPushes:
        speed, mass, friction, direction = (
            np.asarray(x, float).ravel().copy() for x in np.broadcast_arrays(speed, mass, friction, direction)
        )
        defaults = {
            "carriage_mass": scene.pusher_mass,
            "servo_kv": scene.pusher_kv,
            "force_limit": scene.pusher_force_limit,
            "stroke": scene.stroke,
        }
        params = {k: np.full(speed.size, float(defaults.get(k, v) if v is None else v)) for k, v in PARAMETERS.items()}
        return cls(speed, mass, friction, direction, params)

    @property
    def n(self) -> int:
        return int(self.speed.size)

    def subset(self, idx: np.ndarray) -> WorldPushes:
        return WorldPushes(
            self.speed[idx],
            self.mass[idx],
            self.friction[idx],
            self.direction[idx],
            {k: v[idx] for k, v in self.params.items()},
        )

    @staticmethod
    def concat(parts: list[WorldPushes]) -> WorldPushes:
        return WorldPushes(
            *(np.concatenate([getattr(p, f) for p in parts]) for f in ("speed", "mass", "friction", "direction")),
            {k: np.concatenate([p.params[k] for p in parts]) for k in PARAMETERS},
        )


@dataclass(frozen=True)
class WorldResult:
    """Outcome of n pushes, (n,) each: travel along and across the push (m), stop time (s), ok, steps.

    stroke_time: (n,) s from the start of the push until the pusher reached the end of its
      stroke (the pusher's mean speed over the stroke, what its encoders give, is the
      stroke length over it); None where the engine did not record it.
    track: (n, T, 3) the box's travel along and across the push (m) and its yaw (rad) at
      the ``track_times`` asked for (a frame due after the box stopped holds where it
      stopped); None without track times.
    drive_force: (n,) N, the servo's mean force over the second half of the stroke (what a
      pull test's force gauge reads while the box slides steadily); None where the engine
      did not record it.
    """

    displacement: np.ndarray
    lateral: np.ndarray
    stop_time: np.ndarray
    ok: np.ndarray
    steps: np.ndarray
    stroke_time: np.ndarray | None = None
    track: np.ndarray | None = None
    drive_force: np.ndarray | None = None


def _structure_key(p: dict[str, np.ndarray], i: int) -> tuple[float, float, float]:
    return float(p["torsional"][i]), float(p["rolling"][i]), float(p["height"][i])


def world_model(scene: SceneConfig, stepping: WorldStepping, torsional=0.0, rolling=0.0, height=0.0) -> mujoco.MjModel:
    """The scene compiled for the world: its integrator, and the structural deviations given."""
    scene = dataclasses.replace(scene, option={**scene.option, "integrator": stepping.integrator})
    spec = mujoco.MjSpec.from_string(build_xml(scene))
    box = spec.geom("box")
    if torsional > 0 or rolling > 0:
        fr = np.array(box.friction, float)
        fr[1] = torsional
        fr[2] = rolling
        box.friction = fr
        box.condim = 6 if rolling > 0 else 4
    if height != 0.0:
        # a taller (shorter) box of the same mass; the pusher stays at the rig's height
        size = np.array(box.size, float)
        size[2] *= 1.0 + height
        box.size = size
        body = spec.body("box")
        pos = np.array(body.pos, float)
        pos[2] = size[2]
        body.pos = pos
    return spec.compile()


def simulate_world(
    pushes: WorldPushes,
    scene: SceneConfig,
    stepping: WorldStepping | None = None,
    *,
    nthread: int = 0,
    progress: bool = False,
    track_times: np.ndarray | None = None,
) -> WorldResult:
    """Simulate every push of ``pushes`` in the world (batched; one batch per model structure).

    ``track_times``: increasing times (s from the start of the push) at which to record the
    box (:attr:`WorldResult.track`)."""
    stepping = stepping or WorldStepping()
    n = pushes.n
    keys = [_structure_key(pushes.params, i) for i in range(n)]
    out = {f: np.zeros(n) for f in ("displacement", "lateral", "stop_time", "stroke_time", "drive_force")}
    ok = np.zeros(n, bool)
    steps = np.zeros(n, np.int64)
    track = None if track_times is None else np.zeros((n, np.asarray(track_times).size, 3))
    for key in sorted(set(keys)):
        idx = np.array([i for i in range(n) if keys[i] == key])
        model = world_model(scene, stepping, *key)
        res = _run(model, pushes.subset(idx), stepping, nthread=nthread, progress=progress, track_times=track_times)
        for f in out:
            out[f][idx] = getattr(res, f)
        ok[idx] = res.ok
        steps[idx] = res.steps
        if track is not None:
            track[idx] = res.track
    return WorldResult(
        out["displacement"], out["lateral"], out["stop_time"], ok, steps, out["stroke_time"], track, out["drive_force"]
    )


def run_model(
    model: mujoco.MjModel, pushes: WorldPushes, stepping: WorldStepping | None = None, *, nthread: int = 0
) -> WorldResult:
    """Pushes on a compiled push model (a user's MJCF, with the names :mod:`imply.sim.scene` requires) stepped by the
    world's code path at the model's own integrator; the structural parameters (torsional, rolling, height) must be
    nominal."""
    for name in ("torsional", "rolling", "height"):
        if np.any(pushes.params[name] != 0):
            raise ValueError(f"{name} changes the model's structure; edit the MJCF instead")
    return _run(model, pushes, stepping or WorldStepping(), nthread=nthread, progress=False)


def check_track_times(track_times) -> np.ndarray | None:
    """``track_times`` as a float array (None stays None); ValueError unless increasing, non-negative, two or more."""
    if track_times is None:
        return None
    tt = np.asarray(track_times, float)
    if tt.ndim != 1 or tt.size < 2 or np.any(np.diff(tt) <= 0) or tt[0] < 0:
        raise ValueError("track_times must be increasing, non-negative and at least two")
    return tt


def _quat_rotate(q: np.ndarray, v: np.ndarray, inverse: bool = False) -> np.ndarray:
    """Rotate vectors v (n, 3) by unit quaternions q (n, 4, w first), or by their inverse."""
    w, u = q[:, :1], q[:, 1:]
    if inverse:
        u = -u
    t = 2.0 * np.cross(u, v)
    return v + w * t + np.cross(u, t)


def _run(
    model: mujoco.MjModel, p: WorldPushes, st: WorldStepping, *, nthread: int, progress: bool, track_times=None
) -> WorldResult:
    n = p.n
    track_times = check_track_times(track_times)
    prm = p.params
    b = mjbatch.Batch(model, n, nthread=nthread)
    box_body, pusher_body = model.body("box").id, model.body("pusher").id
    box_geom, pusher_geom = model.geom("box").id, model.geom("pusher").id
    servo = model.actuator("servo").id
    # per-push physics on expanded model fields
    b.body("box").mass = p.mass[:, None]
    b.body("box").inertia = model.body_inertia[box_body][None, :] * (p.mass / model.body_mass[box_body])[:, None]
    cm = prm["carriage_mass"]
    b.body("pusher").mass = cm[:, None]
    b.body("pusher").inertia = model.body_inertia[pusher_body][None, :] * (cm / model.body_mass[pusher_body])[:, None]
    friction = b.expand("geom_friction")
    friction[:, box_geom, 0] = p.friction
    solref = b.expand("geom_solref")
    solref[:, pusher_geom, 0] = model.geom_solref[pusher_geom, 0] + prm["pusher_timeconst"]
    solref[:, pusher_geom, 1] = prm["pusher_dampratio"]
    # the contact model: the box-table contact takes the box's solref (its priority is the
    # table's), the pusher-box contact the pusher's friction and solimp (its priority is the box's)
    solref[:, box_geom, 0] = model.geom_solref[box_geom, 0] * prm["table_timeconst"]
    solref[:, box_geom, 1] = model.geom_solref[box_geom, 1] * prm["table_dampratio"]
    friction[:, pusher_geom, 0] = model.geom_friction[pusher_geom, 0] + prm["pusher_friction"]
    if np.any(prm["pusher_impedance"] != 0):
        solimp = b.expand("geom_solimp")
        solimp[:, pusher_geom, 0] = model.geom_solimp[pusher_geom, 0] - prm["pusher_impedance"]
        solimp[:, pusher_geom, 1] = model.geom_solimp[pusher_geom, 1] - prm["pusher_impedance"]
    gain, bias = b.expand("actuator_gainprm"), b.expand("actuator_biasprm")
    gain[:, servo, 0] = prm["servo_kv"]
    bias[:, servo, 2] = -prm["servo_kv"]
    frange = b.expand("actuator_forcerange")
    frange[:, servo, 0] = -prm["force_limit"]
    frange[:, servo, 1] = prm["force_limit"]
    # a table tilted by `tilt` downhill toward table azimuth psi; the scene pushes along its
    # +x, which is table azimuth `direction`: gravity in full, across the push too
    if np.any(prm["tilt"] != 0):
        g = float(np.linalg.norm(model.opt.gravity))
        rel = prm["tilt_azimuth"] - p.direction
        gravity = b.expand("opt.gravity")
        gravity[:, 0] = g * np.sin(prm["tilt"]) * np.cos(rel)
        gravity[:, 1] = g * np.sin(prm["tilt"]) * np.sin(rel)
        gravity[:, 2] = -g * np.cos(prm["tilt"])
    b.set_const()

    # a box-table contact stiffer than the scene's (its time constant's factor below 1) takes every step shortened
    # by that factor, so that each step resolves the contact as the nominal one's does: an underdamped stiff contact
    # stepped at the nominal steps misses the converged slide by about as much as the noise
    shorter = np.minimum(prm["table_timeconst"], 1.0) if st.contact_steps else np.ones(n)
    fine = np.where(p.speed < st.slow_speed, st.slow_push_step, st.push_step) * shorter
    timestep = b.expand("opt.timestep")
    timestep[:] = fine
    b.reset()
    qpos, qvel, ctrl, now, xfrc = (b.bind(f) for f in ("qpos", "qvel", "ctrl", "time", "xfrc_applied"))
    bq = int(model.jnt_qposadr[model.joint("box").id])
    bv = int(model.jnt_dofadr[model.joint("box").id])
    pq = int(model.jnt_qposadr[model.joint("push").id])
    pv = int(model.jnt_dofadr[model.joint("push").id])
    # a free stroke: the box waits 10 m beyond the pusher's reach
    free = prm["free"] != 0
    qpos[free, bq] += 10.0
    start = qpos[:, bq : bq + 3].copy()
    pusher0 = qpos[:, pq].copy()
    stroke = prm["stroke"]
    ctrl[:, servo] = p.speed
    force = b.bind("actuator_force")
    impulse, impulse_time = np.zeros(n), np.zeros(n)

    # which pushes need forces or friction laws at every step
    forced = (prm["viscous"] != 0) | (prm["air_density"] != 0)
    lawful = (prm["aniso"] != 0) | (prm["stribeck"] != 0) | (prm["gradient"] != 0)
    lawful |= (prm["friction_slope"] != 0) | (prm["friction_regularisation"] != 0)
    hooked = forced | lawful
    # the box's cross-sections per body axis (full side lengths), for air drag
    full = 2.0 * np.asarray(model.geom_size[box_geom], float)
    area = np.array([full[1] * full[2], full[0] * full[2], full[0] * full[1]])
    v_prev = np.zeros((n, 3))
    h_prev = fine.copy()

    phase = np.zeros(n, np.int8)  # 0 pushing, 1 release window, 2 sliding, 3 stopped
    window_left = np.zeros(n, np.int64)
    stop_time = np.full(n, st.max_time)
    stroke_time = np.full(n, np.nan)
    steps = np.zeros(n, np.int64)
    speed_before = np.zeros(n)
    track = None if track_times is None else np.zeros((n, track_times.size, 3))
    next_frame = np.zeros(n, np.int64)

    def record(ids: np.ndarray) -> None:
        # a camera frame is taken at the first step that reaches its time (within half a step)
        while ids.size and track is not None:
            k = np.minimum(next_frame[ids], track_times.size - 1)
            due = ids[(next_frame[ids] < track_times.size) & (now[ids] >= track_times[k] - timestep[ids] / 2)]
            if not due.size:
                return
            q = qpos[due, bq : bq + 7]
            track[due, next_frame[due]] = np.stack(
                [q[:, 0] - start[due, 0], q[:, 1] - start[due, 1], yaw_of(q[:, 3:])], 1
            )
            next_frame[due] += 1
            ids = due

    record(np.arange(n))
    bar = tqdm(total=n, desc="world pushes stopped", unit="push", disable=not progress, leave=False)
    active = np.arange(n)
    while active.size:
        # -- stroke end: the step that would pass the stroke is shortened to end on it
        pushing = active[phase[active] == 0]
        ending = np.zeros(0, np.int64)
        if pushing.size:
            left = (stroke[pushing] - (qpos[pushing, pq] - pusher0[pushing])) / np.maximum(
                qvel[pushing, pv] * fine[pushing], 1e-12
            )
            ends = (left < 1.0) | (now[pushing] + fine[pushing] >= st.max_time)
            ending = pushing[ends]
            if ending.size:
                timestep[ending] = np.clip(left[ends], 1e-3, 1.0) * fine[ending]
        # -- forces and friction laws at the predicted mid-step state
        hk = active[hooked[active]]
        if hk.size:
            h = timestep[hk]
            v_now = qvel[hk, bv : bv + 3]
            v_mid = v_now + (v_now - v_prev[hk]) / h_prev[hk, None] * h[:, None] / 2.0
            v_prev[hk] = v_now
            h_prev[hk] = h
            f_sel = forced[hk]
            if f_sel.any():
                sel, v = hk[f_sel], v_mid[f_sel]
                f = -prm["viscous"][sel, None] * v
                q = qpos[sel, bq + 3 : bq + 7]
                vl = _quat_rotate(q, v, inverse=True)
                fl = -0.5 * prm["air_density"][sel, None] * area[None, :] * np.abs(vl) * vl
                xfrc[sel, box_body, :3] = f + _quat_rotate(q, fl)
            l_sel = lawful[hk]
            if l_sel.any():
                sel, v, hl = hk[l_sel], v_mid[l_sel], h[l_sel]
                speed = np.hypot(v[:, 0], v[:, 1])
                theta = np.where(speed > 1e-9, np.arctan2(v[:, 1], v[:, 0]), 0.0) + p.direction[sel]
                factor = 1.0 + prm["aniso"][sel] * np.cos(2.0 * (theta - prm["aniso_axis"][sel]))
                factor *= 1.0 + prm["stribeck"][sel] * np.exp(-((speed / prm["stribeck_speed"][sel]) ** 2))
                xy = qpos[sel, bq : bq + 2] - start[sel, :2] + v[:, :2] * hl[:, None] / 2.0
                rel = prm["gradient_azimuth"][sel] - p.direction[sel]
                along = xy[:, 0] * np.cos(rel) + xy[:, 1] * np.sin(rel)
                factor *= np.maximum(1.0 + prm["gradient"][sel] * along, 0.2)
                # velocity-dependent and regularised Coulomb friction; the regularised law keeps a share
                # r at rest, so that a box on a tilted table still stops
                factor *= np.maximum(1.0 + prm["friction_slope"][sel] * (speed - prm["friction_slope_speed"][sel]), 0.2)
                eps, rest = prm["friction_regularisation"][sel], prm["friction_rest_share"][sel]
                factor *= np.where(eps > 0, rest + (1.0 - rest) * np.tanh(speed / np.maximum(eps, 1e-12)), 1.0)
                friction[sel, box_geom, 0] = p.friction[sel] * factor
        sliding = active[phase[active] == 2]
        released = active[phase[active] >= 1]
        if released.size:
            speed_before[released] = np.hypot(qvel[released, bv], qvel[released, bv + 1])
        b.step(ids=active, nstep=1)
        steps[active] += 1
        record(active)
        if pushing.size:
            # the servo's force over the second half of the stroke (a pull test's gauge)
            late = pushing[qpos[pushing, pq] - pusher0[pushing] > stroke[pushing] / 2]
            impulse[late] += force[late, servo] * timestep[late]
            impulse_time[late] += timestep[late]
        # -- phase changes
        if ending.size:
            stroke_time[ending] = now[ending]
            timestep[ending] = fine[ending]
            ctrl[ending, servo] = 0.0  # the servo brakes
            phase[ending] = 1
            window_left[ending] = 0
            window_left[ending] = np.round(st.release_window / fine[ending]).astype(np.int64)
        if released.size:
            # the stop time: when the speed crosses stop_speed (interpolated within the step)
            speed = np.hypot(qvel[released, bv], qvel[released, bv + 1])
            slowed = (speed < st.stop_speed) & (stop_time[released] >= st.max_time)
            if slowed.any():
                ids, s0, s1 = released[slowed], speed_before[released[slowed]], speed[slowed]
                frac = np.clip(np.nan_to_num((s0 - st.stop_speed) / np.maximum(s0 - s1, 1e-300), nan=1.0), 0.0, 1.0)
                stop_time[ids] = now[ids] - timestep[ids] * (1.0 - frac)
        win = active[phase[active] == 1]
        if win.size:
            window_left[win] -= 1
            over = win[window_left[win] <= 0]
            phase[over] = 2
            timestep[over] = st.slide_step * shorter[over]
        if sliding.size:
            speed = np.hypot(qvel[sliding, bv], qvel[sliding, bv + 1])
            rest = (speed < st.rest_speed) | ~np.isfinite(speed) | (now[sliding] >= st.max_time)
            done = sliding[rest]
            if done.size:
                phase[done] = 3
                xfrc[done] = 0.0
                bar.update(done.size)
        active = active[phase[active] < 3]
    bar.close()
    disp = qpos[:, bq] - start[:, 0]
    lateral = qpos[:, bq + 1] - start[:, 1]
    x, y = qpos[:, bq + 4], qpos[:, bq + 5]
    tipped = np.arccos(np.clip(1.0 - 2.0 * (x * x + y * y), -1.0, 1.0)) >= 0.1
    ok = np.isfinite(disp) & (now < st.max_time) & (stop_time < st.max_time) & ~tipped & (disp > 0)
    if track is not None:
        # frames due after the box came to rest see it where it stopped
        final = np.stack([disp, lateral, yaw_of(qpos[:, bq + 3 : bq + 7])], 1)
        late = np.arange(track_times.size)[None, :] >= next_frame[:, None]
        track = np.where(late[:, :, None], final[:, None, :], track)
    drive_force = np.where(impulse_time > 0, impulse / np.maximum(impulse_time, 1e-300), np.nan)
    return WorldResult(disp, lateral, stop_time, ok, steps, stroke_time, track, drive_force)
