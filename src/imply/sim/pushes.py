"""Many pushes at once on ``mujoco.batch``: one simulation per (speed, object).

How a push is stepped, and why (each choice measured against a timestep-to-zero
reference with ``imply table check``; the table's metadata records the result):

1. Pushing. The servo is commanded the push speed and the simulation advances at a
   fine step, ``timestep / push_substeps`` (half that below ``slow_push_speed``). The pusher's servo time constant
   (pusher mass / kv, 2.5 ms on the built-in scene) is the fastest motion in the scene,
   and at a 1 ms step log d was off by up to 0.15 from the converged answer. The scene
   integrates with MuJoCo's semi-implicit ``Euler``: ``implicitfast`` treats the servo's
   damping implicitly, which at a step h behaves like a pusher heavier by h kv and
   converges several times more slowly. The stroke ends exactly where the pusher
   reaches it: the last substep is shortened to the fraction of it that is left.
2. Release window. For ``release_window`` seconds after the stroke the fine step
   continues while the braking pusher separates from the box.
3. Sliding. The rest of the slide runs at the model's ``timestep`` until the box has
   settled (all linear speeds below ``settle_speed``) or ``max_time`` has passed; a
   slide too short for ``slide_steps`` such steps (judged from Coulomb friction) uses
   a halving of it, down to the fine step.

Semi-implicit Euler moves a body by h times its new velocity, so a segment of steps
of length h adds h (v_end - v_start) / 2 to the travel that the trapezoid rule would
give. Over a push from rest to rest at one step size these terms cancel; with a
fine push and a coarse slide they do not, and they would leave an error of the order
of the coarse step times the release speed. Every change of step therefore adds the
term back (:class:`_TravelCorrection`), so displacements are the trapezoid-rule
travel: exact for a constant deceleration whatever the step, which is what lets the
slide use the coarse step.

Per-push mass and friction are written into the batch's expanded model fields (the
inertia scaled with the mass, so the box stays a uniform-density box). Per-push box
geometry needs a model each, which are built from the scene and run with
``Batch.set_models``.
"""

from __future__ import annotations

import copy
import logging
from dataclasses import dataclass

import mujoco
import numpy as np
from mujoco import batch as mjbatch
from tqdm.auto import tqdm

from imply.sim.scene import COMMAND_OFFSET, SceneConfig, build_model, model_numeric

log = logging.getLogger("imply.sim")

# a push may take at most this many substeps (max_time / fine step); beyond it a
# mistyped timestep would look like a hang
MAX_SUBSTEPS_PER_PUSH = 10_000_000


@dataclass(frozen=True)
class PushResult:
    """Outcome of n pushes; every array has shape (n,).

    displacement: box travel along the push axis (+x), metres.
    lateral: box travel across the push axis (y), metres.
    stop_time: time at which the box was seen settled, seconds (max_time if never).
    stroke_time: time at which the pusher reached the end of its stroke, seconds (its mean
      speed over the stroke, what a robot's encoders give, is the stroke length over it).
    tilt: final angle between the box's up axis and the world's, radians.
    ok: finite, settled, and neither tipped (tilt < 0.1 rad) nor deflected sideways.
    substeps: MuJoCo steps each push took (for benchmarks).
    """

    displacement: np.ndarray
    lateral: np.ndarray
    stop_time: np.ndarray
    tilt: np.ndarray
    ok: np.ndarray
    substeps: np.ndarray | None = None
    stroke_time: np.ndarray | None = None


@dataclass(frozen=True)
class PushStepping:
    """How a push model is stepped (its ``<option timestep>`` and ``<custom>`` numerics)."""

    timestep: float
    push_substeps: int
    release_window: float
    stroke: float
    settle_speed: float
    max_time: float
    slide_steps: int = 0
    slow_push_speed: float = 0.0

    @property
    def fine_step(self) -> float:
        """Step while pushing and in the release window, seconds (halved for slow pushes)."""
        return self.timestep / self.push_substeps

    def fine_steps(self, speeds: np.ndarray) -> np.ndarray:
        """Each push's fine step (n,): a slow push lasts longer and rocks the box more often
        (its contacts switch between edges), so it takes twice as many substeps."""
        return np.where(np.asarray(speeds) < self.slow_push_speed, self.fine_step / 2, self.fine_step)

    @classmethod
    def of(cls, model: mujoco.MjModel) -> PushStepping:
        """The stepping a push model asks for; ValueError if it cannot finish a push."""
        defaults = SceneConfig()
        stepping = cls(
            timestep=float(model.opt.timestep),
            push_substeps=int(round(model_numeric(model, "push_substeps", float(defaults.push_substeps)))),
            release_window=model_numeric(model, "release_window", defaults.release_window),
            stroke=model_numeric(model, "stroke"),
            settle_speed=model_numeric(model, "settle_speed", defaults.settle_speed),
            max_time=model_numeric(model, "max_time", defaults.max_time),
            slide_steps=int(round(model_numeric(model, "slide_steps", float(defaults.slide_steps)))),
            slow_push_speed=model_numeric(model, "slow_push_speed", defaults.slow_push_speed),
        )
        stepping.check()
        return stepping

    def check(self) -> None:
        for name in ("timestep", "stroke", "settle_speed", "max_time"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"the push model's {name} must be positive and finite, not {value!r}")
        if self.push_substeps < 1:
            raise ValueError(f"the push model's push_substeps must be at least 1, not {self.push_substeps}")
        if not (np.isfinite(self.release_window) and self.release_window >= 0):
            raise ValueError(f"the push model's release_window must be >= 0, not {self.release_window!r}")
        if self.max_time / self.fine_step > MAX_SUBSTEPS_PER_PUSH:
            raise ValueError(
                f"a push could take {self.max_time / self.fine_step:.3g} substeps (max_time {self.max_time:g} s at "
                f"{self.fine_step:g} s); at most {MAX_SUBSTEPS_PER_PUSH:.0e} are allowed: raise the timestep"
            )


@dataclass(frozen=True)
class PushJoints:
    """Where a push model keeps the box's and the pusher's state."""

    box_qpos: int
    box_dof: int
    push_qpos: int
    push_dof: int
    servo: int

    @classmethod
    def of(cls, model: mujoco.MjModel) -> PushJoints:
        def find(kind: str, name: str):
            try:
                return getattr(model, kind)(name)
            except KeyError:
                raise ValueError(
                    f"the push model has no {kind} named '{name}' (it needs body and geom 'box' with a free "
                    "joint, slide joint 'push' and velocity actuator 'servo')"
                ) from None

        box = find("body", "box")
        find("geom", "box")
        if box.jntnum[0] < 1 or model.jnt_type[box.jntadr[0]] != mujoco.mjtJoint.mjJNT_FREE:
            raise ValueError("the push model's body 'box' must have a free joint as its first joint")
        box_jnt = int(box.jntadr[0])
        push = find("joint", "push")
        if model.jnt_type[push.id] != mujoco.mjtJoint.mjJNT_SLIDE:
            raise ValueError("the push model's joint 'push' must be a slide joint")
        return cls(
            box_qpos=int(model.jnt_qposadr[box_jnt]),
            box_dof=int(model.jnt_dofadr[box_jnt]),
            push_qpos=int(model.jnt_qposadr[push.id]),
            push_dof=int(model.jnt_dofadr[push.id]),
            servo=int(find("actuator", "servo").id),
        )


def _as_column(values, n: int, name: str) -> np.ndarray | None:
    if values is None:
        return None
    arr = np.broadcast_to(np.asarray(values, dtype=float), (n,)).copy()
    if not np.all(np.isfinite(arr)) or np.any(arr <= 0):
        raise ValueError(f"{name} must be finite and positive")
    return arr


def simulate_pushes(
    speeds,
    masses=None,
    frictions=None,
    half_extents=None,
    *,
    scene: SceneConfig | None = None,
    model: mujoco.MjModel | None = None,
    nthread: int = 0,
    chunk: int = 10,
    progress: bool = False,
) -> PushResult:
    """Simulate one push per entry of ``speeds`` (m/s), all in one batch (:func:`simulate_pushes_run`'s result)."""
    return simulate_pushes_run(
        speeds,
        masses,
        frictions,
        half_extents,
        scene=scene,
        model=model,
        nthread=nthread,
        chunk=chunk,
        progress=progress,
    ).result


def simulate_pushes_run(
    speeds,
    masses=None,
    frictions=None,
    half_extents=None,
    *,
    scene: SceneConfig | None = None,
    model: mujoco.MjModel | None = None,
    nthread: int = 0,
    chunk: int = 10,
    progress: bool = False,
    frame_times: np.ndarray | None = None,
) -> PushRun:
    """Simulate one push per entry of ``speeds`` (m/s), all in one batch, recording the box at ``frame_times``.

    Args:
      speeds: (n,) commanded pusher speeds.
      masses, frictions: (n,) or scalar box mass (kg) and sliding friction; None keeps
        the model's.
      half_extents: (n, 3) or (3,) box half-extents (m) per push; None keeps the
        model's. Only with the built-in scene (``model`` None).
      scene: settings of the built-in scene; ignored when ``model`` is given.
      model: a user's push model (see :mod:`imply.sim.scene` for the names it needs).
      nthread: threads of the batch (0: all CPUs).
      chunk: substeps between checks for settled boxes while sliding.
      progress: show a progress bar of settled pushes.
      frame_times: (T,) increasing times (s from the start of the push) at which to record the box
        (:attr:`PushRun.frames_box_qpos`); None records nothing.
    """
    speeds = np.atleast_1d(np.asarray(speeds, dtype=float)).ravel()
    n = speeds.size
    if not np.all(np.isfinite(speeds)) or np.any(speeds <= 0):
        raise ValueError("speeds must be finite and positive")
    masses = _as_column(masses, n, "masses")
    frictions = _as_column(frictions, n, "frictions")
    if model is not None and half_extents is not None:
        raise ValueError("half_extents can only vary with the built-in scene, not a user model")

    if model is None and half_extents is not None:
        he = np.broadcast_to(np.asarray(half_extents, dtype=float), (n, 3))
        if not np.all(np.isfinite(he)) or np.any(he <= 0):
            raise ValueError("half_extents must be finite and positive")
        batch, per_sim = batch_with_geometry(speeds.size, he, masses, frictions, scene=scene, nthread=nthread)
        model = per_sim[0]
    else:
        model = model if model is not None else build_model(scene or SceneConfig())
        # a user's model is checked before anything reads it
        PushJoints.of(model)
        PushStepping.of(model)
        per_sim = None
        batch = mjbatch.Batch(model, n, nthread=nthread)
        _set_batch_physics(batch, model, masses, frictions)
    run = run_pushes(batch, model, speeds, models=per_sim, chunk=chunk, progress=progress, frame_times=frame_times)
    if not run.result.ok.all():
        log.warning(
            "%d of %d pushes failed checks (unsettled, tipped, NaN or deflected)", int((~run.result.ok).sum()), n
        )
    return run


def batch_with_geometry(
    n: int,
    half_extents: np.ndarray,
    masses: np.ndarray | None,
    frictions: np.ndarray | None,
    *,
    scene: SceneConfig | None,
    nthread: int,
) -> tuple[mjbatch.Batch, list[mujoco.MjModel]]:
    """A batch of n built-in pushes, each with its own box size (n, 3), mass and friction."""
    scene = scene or SceneConfig()
    uniq, inverse = np.unique(np.asarray(half_extents, dtype=float), axis=0, return_inverse=True)
    built = [build_model(scene, half_extents=tuple(row)) for row in uniq]
    # set_models excludes expanded fields, so each push gets its own model copy
    per_sim = []
    for i, k in enumerate(inverse.ravel()):
        mi = copy.copy(built[k])
        set_box_physics(mi, None if masses is None else masses[i], None if frictions is None else frictions[i])
        per_sim.append(mi)
    batch = mjbatch.Batch(built[0], n, nthread=nthread)
    batch.set_models(per_sim)
    return batch, per_sim


def _set_batch_physics(
    batch: mjbatch.Batch, model: mujoco.MjModel, masses: np.ndarray | None, frictions: np.ndarray | None
) -> None:
    box = model.body("box").id
    n = batch.nsim
    if masses is not None:
        m0 = float(model.body_mass[box])
        batch.body("box").mass = masses[:, None]
        batch.body("box").inertia = model.body_inertia[box][None, :] * (masses / m0)[:, None]
    if frictions is not None:
        gid = model.geom("box").id
        fr = np.tile(model.geom_friction[gid], (n, 1))
        fr[:, 0] = frictions
        batch.geom("box").friction = fr
    if masses is not None:
        # derived constants (subtree masses, constraint scaling) follow the new masses
        batch.set_const()


@dataclass(frozen=True)
class PushRun:
    """A finished :func:`run_pushes`: the result, and the states recorded at frame times.

    frames_box_qpos: (n, T, 7) box free-joint position (x, y as trapezoid-rule travel)
      and quaternion at each of the T frame times; None without frame times.
    frames_pusher: (n, T) pusher slide at each frame time.
    frames_time: (n, T) simulation time at which each frame was taken (frames due after
      the box settled hold the final state and their nominal time).
    final_box_qpos: (n, 7) the box at rest, x and y corrected as the displacement is.
    final_pusher: (n,) the pusher's final slide.
    """

    result: PushResult
    frames_box_qpos: np.ndarray | None
    frames_pusher: np.ndarray | None
    frames_time: np.ndarray | None
    final_box_qpos: np.ndarray
    final_pusher: np.ndarray


def _sliding_friction(batch: mjbatch.Batch, model: mujoco.MjModel, models: list[mujoco.MjModel] | None) -> np.ndarray:
    """Each simulation's sliding friction coefficient of the box, (n,)."""
    gid = model.geom("box").id
    if models is not None:
        return np.array([m.geom_friction[gid, 0] for m in models])
    return np.array(batch.geom("box").friction, dtype=float).reshape(batch.nsim, -1)[:, 0]


class _Timesteps:
    """Per-simulation timesteps of a batch, on expanded fields or on caller models."""

    def __init__(self, batch: mjbatch.Batch, models: list[mujoco.MjModel] | None, value: np.ndarray) -> None:
        self._batch = batch
        self._models = models
        if models is None:
            self.values = batch.expand("opt.timestep")
            self.values[:] = value
        else:
            self.values = np.full(batch.nsim, value)
            self._write(np.arange(batch.nsim))

    def set(self, ids: np.ndarray, value) -> None:
        self.values[ids] = value
        if self._models is not None:
            self._write(ids)

    def _write(self, ids: np.ndarray) -> None:
        for i in ids:
            self._models[i].opt.timestep = self.values[i]
        self._batch.set_models(self._models)


class _TravelCorrection:
    """Keeps the box's travel at the trapezoid rule's value across changes of step (see module doc)."""

    def __init__(self, n: int) -> None:
        self.offset = np.zeros((n, 2))

    def step_changes(self, ids: np.ndarray, old: np.ndarray, new, velocity_xy: np.ndarray) -> None:
        self.offset[ids] += (np.asarray(new) - old)[..., None] * velocity_xy / 2.0

    def travel_xy(self, ids: np.ndarray, raw_xy: np.ndarray, step: np.ndarray, velocity_xy: np.ndarray) -> np.ndarray:
        """Trapezoid-rule positions of simulations ``ids`` from MuJoCo's (their current step, velocity)."""
        return raw_xy + self.offset[ids] - step[ids, None] * velocity_xy / 2.0


def run_pushes(
    batch: mjbatch.Batch,
    model: mujoco.MjModel,
    speeds: np.ndarray,
    *,
    models: list[mujoco.MjModel] | None = None,
    frame_times: np.ndarray | None = None,
    chunk: int = 10,
    progress: bool = False,
) -> PushRun:
    """Push every simulation of ``batch`` at its speed (n,) through the three phases of the module doc.

    Args:
      batch: n simulations of one push model, physics already set (not yet reset).
      model: that push model (its names and stepping are read from it).
      speeds: (n,) commanded pusher speeds, m/s.
      models: the caller models of a batch run with ``set_models`` (per-push geometry).
      frame_times: increasing times (s) at which to record the box and the pusher.
      chunk: substeps between checks for settled boxes while sliding.
      progress: show a progress bar of settled pushes.
    """
    stepping = PushStepping.of(model)
    joints = PushJoints.of(model)
    n = batch.nsim
    # a corrected scene's command mapping: the servo is told the speed plus the offset
    speeds = np.asarray(speeds, dtype=float) + model_numeric(model, COMMAND_OFFSET, 0.0)
    if np.any(speeds <= 0):
        raise ValueError(f"the scene's {COMMAND_OFFSET} leaves a commanded speed at or below 0 m/s")
    fine, coarse = stepping.fine_steps(speeds), stepping.timestep
    timesteps = _Timesteps(batch, models, fine)
    batch.reset()

    qpos, qvel, ctrl, now = batch.bind("qpos"), batch.bind("qvel"), batch.bind("ctrl"), batch.bind("time")
    bq, bv, pq, pv = joints.box_qpos, joints.box_dof, joints.push_qpos, joints.push_dof
    start = qpos[:, bq : bq + 3].copy()
    pusher0 = qpos[:, pq].copy()
    travel = _TravelCorrection(n)
    substeps = np.zeros(n, dtype=np.int64)
    frames = _Frames(frame_times, n) if frame_times is not None else None

    def box_xy(ids: np.ndarray) -> np.ndarray:
        return travel.travel_xy(ids, qpos[ids, bq : bq + 2], timesteps.values, qvel[ids, bv : bv + 2])

    def record(ids: np.ndarray) -> None:
        if frames is not None:
            frames.record(ids, now, timesteps.values, qpos[:, bq : bq + 7], box_xy, qpos[:, pq] - pusher0)

    def change_step(ids: np.ndarray, new) -> None:
        travel.step_changes(ids, timesteps.values[ids].copy(), new, qvel[ids, bv : bv + 2])
        timesteps.set(ids, new)

    def advance(ids: np.ndarray, counts: np.ndarray) -> None:
        """Step each simulation ``ids[i]`` by ``counts[i]`` substeps, stopping at due frames."""
        left = np.asarray(counts, dtype=np.int64).copy()
        while ids.size:
            k = left if frames is None else np.minimum(left, frames.steps_to_next(ids, now, timesteps.values))
            if (k == k[0]).all():
                # one call when every count is the same (with a frame due at every step, always)
                taken = k[0]
                batch.step(ids=ids, nstep=int(taken))
            else:
                # one call per power of two: a handful of calls however the counts differ
                taken = 2 ** np.floor(np.log2(np.maximum(k, 1))).astype(np.int64)
                for b in np.unique(taken):
                    sel = ids[taken == b]
                    batch.step(ids=sel, nstep=int(b))
            substeps[ids] += taken
            left -= taken
            record(ids)
            keep = left > 0
            ids, left = ids[keep], left[keep]

    record(np.arange(n))

    # 1. pushing: full fine substeps while the stroke is far, then one shortened to end on it
    ctrl[:, :] = 0.0
    ctrl[:, joints.servo] = speeds
    stroke_time = np.full(n, np.nan)
    pushing = np.arange(n)
    while pushing.size:
        gap = stepping.stroke - qpos[pushing, pq]
        # the pusher cannot cover the gap in fewer substeps than at the larger of its speed
        # and the command (it approaches the command from below); half of that is safe
        pace = np.maximum(np.maximum(qvel[pushing, pv], speeds[pushing]), 1e-12) * fine[pushing]
        safe = np.floor(np.nan_to_num(0.5 * gap / pace, nan=0.0, posinf=0.0)).astype(np.int64)
        timeout = np.ceil((stepping.max_time - now[pushing]) / fine[pushing]).astype(np.int64)
        safe = np.minimum(safe, np.maximum(timeout - 1, 0))
        far = safe >= 2
        if far.any():
            advance(pushing[far], safe[far])
        near = pushing[~far]
        if near.size:
            left = (stepping.stroke - qpos[near, pq]) / np.maximum(qvel[near, pv] * fine[near], 1e-12)
            ends = (left < 1.0) | ~np.isfinite(left) | (now[near] + fine[near] >= stepping.max_time)
            ending = near[ends]
            fraction = np.clip(np.nan_to_num(left[ends], nan=1.0), 1e-3, 1.0)
            if ending.size:
                change_step(ending, fraction * fine[ending])
            batch.step(ids=near, nstep=1)
            substeps[near] += 1
            if ending.size:
                change_step(ending, fine[ending])
                ctrl[ending, joints.servo] = 0.0  # the servo brakes
                stroke_time[ending] = now[ending]
            record(near)
            pushing = np.setdiff1d(pushing, ending, assume_unique=True)

    # 2. release window at the fine step
    everyone = np.arange(n)
    window = np.round(stepping.release_window / fine).astype(np.int64)
    if window.any():
        advance(everyone[window > 0], window[window > 0])

    # 3. sliding at the model's step until settled, or finer for a slide too short to
    # take slide_steps of it (its length judged from Coulomb friction alone)
    slide_step = np.full(n, coarse)
    if stepping.slide_steps:
        decel = _sliding_friction(batch, model, models) * float(np.linalg.norm(model.opt.gravity))
        with np.errstate(divide="ignore", invalid="ignore"):
            wanted = np.abs(qvel[:, bv]) / decel / stepping.slide_steps
        wanted = np.nan_to_num(wanted, nan=coarse, posinf=coarse)
        # halvings of the model's step, down to the fine one
        halvings = np.clip(np.ceil(np.log2(coarse / np.maximum(wanted, 1e-300))), 0, np.log2(coarse / fine))
        slide_step = coarse / 2.0**halvings
    change_step(everyone, slide_step)
    stop_time = np.full(n, stepping.max_time)
    active = np.arange(n)
    bar = tqdm(total=n, desc="pushes settled", unit="push", disable=not progress, leave=False)
    while active.size:
        advance(active, np.full(active.size, chunk))
        speed = np.abs(qvel[active, bv : bv + 3]).max(axis=1)
        settled = (speed < stepping.settle_speed) | ~np.isfinite(speed)
        timed_out = now[active] >= stepping.max_time
        stop_time[active[settled]] = now[active[settled]]
        done = settled | timed_out
        bar.update(int(done.sum()))
        active = active[~done]
    bar.close()

    final = qpos[:, bq : bq + 7].copy()
    final[:, :2] = box_xy(everyone)
    disp = final[:, 0] - start[:, 0]
    lateral = final[:, 1] - start[:, 1]
    tilt, ok = push_checks(final, disp, lateral, stop_time, stepping.max_time)
    result = PushResult(
        displacement=disp,
        lateral=lateral,
        stop_time=stop_time,
        tilt=tilt,
        ok=ok,
        substeps=substeps,
        stroke_time=stroke_time,
    )
    final_pusher = qpos[:, pq] - pusher0
    if frames is None:
        return PushRun(result, None, None, None, final, final_pusher)
    frames.fill_after_rest(final, final_pusher)
    return PushRun(result, frames.box, frames.pusher, frames.time, final, final_pusher)


# steps to the next frame of a simulation that has taken its last
_NO_FRAME_DUE = np.iinfo(np.int64).max // 4


class _Frames:
    """Box and pusher states of n pushes at given times."""

    def __init__(self, frame_times, n: int) -> None:
        ft = np.asarray(frame_times, dtype=float)
        if ft.ndim != 1 or ft.size < 1 or np.any(np.diff(ft) <= 0) or ft[0] < 0:
            raise ValueError("frame_times must be increasing and non-negative")
        self.times = ft
        self.box = np.zeros((n, ft.size, 7))
        self.pusher = np.zeros((n, ft.size))
        self.time = np.zeros((n, ft.size))
        self.next = np.zeros(n, dtype=np.int64)
        # each simulation's next frame time (inf once all are taken), kept beside ``next``: it is read at every step
        self.due = np.full(n, ft[0])

    def steps_to_next(self, ids: np.ndarray, now: np.ndarray, steps: np.ndarray) -> np.ndarray:
        """Substeps until each simulation's next frame is due (at least 1)."""
        due = self.due[ids]
        with np.errstate(invalid="ignore"):
            k = np.ceil((due - now[ids]) / steps[ids] - 0.5)
        return np.where(np.isfinite(k), np.maximum(k, 1), _NO_FRAME_DUE).astype(np.int64)

    def record(self, ids, now, steps, box_qpos, box_xy, pusher) -> None:
        # a frame is due once simulation time reaches it within half a step
        while ids.size:
            due = ids[now[ids] >= self.due[ids] - steps[ids] / 2]
            if not due.size:
                return
            k = self.next[due]
            state = box_qpos[due].copy()
            state[:, :2] = box_xy(due)
            self.box[due, k] = state
            self.pusher[due, k] = pusher[due]
            self.time[due, k] = now[due]
            self.next[due] = k + 1
            self.due[due] = np.where(
                k + 1 < self.times.size, self.times[np.minimum(k + 1, self.times.size - 1)], np.inf
            )
            ids = due

    def fill_after_rest(self, final_box: np.ndarray, final_pusher: np.ndarray) -> None:
        """Frames due after a box settled show it at rest, at their nominal times."""
        for k in range(self.times.size):
            missing = self.next <= k
            self.box[missing, k] = final_box[missing]
            self.pusher[missing, k] = final_pusher[missing]
            self.time[missing, k] = self.times[k]


def push_checks(
    final_box_qpos: np.ndarray, disp: np.ndarray, lateral: np.ndarray, stop_time: np.ndarray, max_time: float
) -> tuple[np.ndarray, np.ndarray]:
    """Tilt of each box at rest (radians) and whether its push passes :class:`PushResult`'s checks."""
    # angle of the box's z axis from vertical, from the quaternion (w, x, y, z)
    x, y = final_box_qpos[:, 4], final_box_qpos[:, 5]
    tilt = np.arccos(np.clip(1.0 - 2.0 * (x * x + y * y), -1.0, 1.0))
    ok = (
        np.isfinite(disp)
        & (stop_time < max_time)
        & (tilt < 0.1)
        & (np.abs(lateral) < 0.1 * np.maximum(np.abs(disp), 1e-3) + 1e-3)
    )
    return tilt, ok


def set_box_physics(model: mujoco.MjModel, mass: float | None, friction: float | None) -> None:
    """Give a push model's box this mass (inertia scaled along) and sliding friction, in place."""
    box = model.body("box").id
    if mass is not None:
        scale = mass / float(model.body_mass[box])
        model.body_mass[box] = mass
        model.body_inertia[box] *= scale
    if friction is not None:
        model.geom_friction[model.geom("box").id, 0] = friction
    if mass is not None:
        mujoco.mj_setConst(model, mujoco.MjData(model))
