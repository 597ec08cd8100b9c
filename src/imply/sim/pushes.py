"""Many pushes at once on ``mujoco.batch``: one simulation per (speed, object).

A push runs in two phases. While pushing, the servo is commanded the push speed and
each simulation is stepped one substep at a time, so that the stroke can end on the
substep where the pusher reaches it (the last substep's command is scaled to the
fraction of it left, which keeps the displacement smooth in speed). After the stroke
the servo brakes the pusher and simulations advance in chunks until the box has
settled (all linear speeds below ``settle_speed``) or ``max_time`` has passed.

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

from imply.sim.scene import SceneConfig, build_model, model_numeric

log = logging.getLogger("imply.sim")


@dataclass(frozen=True)
class PushResult:
    """Outcome of n pushes; every array has shape (n,).

    displacement: box travel along the push axis (+x), metres.
    lateral: box travel across the push axis (y), metres.
    stop_time: time at which the box was seen settled, seconds (max_time if never).
    tilt: final angle between the box's up axis and the world's, radians.
    ok: finite, settled, and neither tipped (tilt < 0.1 rad) nor deflected sideways.
    """

    displacement: np.ndarray
    lateral: np.ndarray
    stop_time: np.ndarray
    tilt: np.ndarray
    ok: np.ndarray


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
    chunk: int = 25,
    progress: bool = False,
) -> PushResult:
    """Simulate one push per entry of ``speeds`` (m/s), all in one batch.

    Args:
      speeds: (n,) commanded pusher speeds.
      masses, frictions: (n,) or scalar box mass (kg) and sliding friction; None keeps
        the model's.
      half_extents: (n, 3) or (3,) box half-extents (m) per push; None keeps the
        model's. Only with the built-in scene (``model`` None).
      scene: settings of the built-in scene; ignored when ``model`` is given.
      model: a user's push model (see :mod:`imply.sim.scene` for the names it needs).
      nthread: threads of the batch (0: all CPUs).
      chunk: substeps per call while waiting for boxes to settle.
      progress: show a progress bar of settled pushes.
    """
    speeds = np.atleast_1d(np.asarray(speeds, dtype=float)).ravel()
    n = speeds.size
    if not np.all(np.isfinite(speeds)) or np.any(speeds <= 0):
        raise ValueError("speeds must be finite and positive")
    masses = _as_column(masses, n, "masses")
    frictions = _as_column(frictions, n, "frictions")

    if model is not None and half_extents is not None:
        raise ValueError("half_extents can only vary with the built-in scene, not a user model")
    scene = scene or SceneConfig()
    geom_models: list[mujoco.MjModel] | None = None
    if model is None:
        if half_extents is None:
            model = build_model(scene)
        else:
            he = np.broadcast_to(np.asarray(half_extents, dtype=float), (n, 3))
            if not np.all(np.isfinite(he)) or np.any(he <= 0):
                raise ValueError("half_extents must be finite and positive")
            uniq, inverse = np.unique(he, axis=0, return_inverse=True)
            built = [build_model(scene, half_extents=tuple(row)) for row in uniq]
            model = built[0]
            geom_models = [built[i] for i in inverse.ravel()]

    stroke = model_numeric(model, "stroke")
    settle_speed = model_numeric(model, "settle_speed", 1e-4)
    max_time = model_numeric(model, "max_time", 4.0)
    box = model.body("box")
    box_jnt = int(box.jntadr[0])
    if model.jnt_type[box_jnt] != mujoco.mjtJoint.mjJNT_FREE:
        raise ValueError("the push model's body 'box' must have a free joint as its first joint")
    bq = int(model.jnt_qposadr[box_jnt])
    bv = int(model.jnt_dofadr[box_jnt])
    push_jnt = model.joint("push").id
    pq = int(model.jnt_qposadr[push_jnt])
    pv = int(model.jnt_dofadr[push_jnt])
    servo = model.actuator("servo").id

    batch = mjbatch.Batch(model, n, nthread=nthread)
    if geom_models is not None:
        # set_models excludes expanded fields, so each push gets its own model copy
        per_sim = []
        for i, gm in enumerate(geom_models):
            mi = copy.copy(gm)
            set_box_physics(mi, None if masses is None else masses[i], None if frictions is None else frictions[i])
            per_sim.append(mi)
        batch.set_models(per_sim)
    else:
        if masses is not None:
            m0 = float(model.body_mass[box.id])
            batch.body("box").mass = masses[:, None]
            batch.body("box").inertia = model.body_inertia[box.id][None, :] * (masses / m0)[:, None]
        if frictions is not None:
            gid = model.geom("box").id
            fr = np.tile(model.geom_friction[gid], (n, 1))
            fr[:, 0] = frictions
            batch.geom("box").friction = fr
        if masses is not None:
            # derived constants (subtree masses, constraint scaling) follow the new masses
            batch.set_const()
    batch.reset()

    qpos = batch.bind("qpos")
    qvel = batch.bind("qvel")
    now = batch.bind("time")
    start = qpos[:, bq : bq + 3].copy()
    stop_time = np.full(n, max_time)

    drive_stroke(batch, speeds, stroke=stroke, max_time=max_time, push_qpos=pq, push_dof=pv, servo=servo)

    active = np.arange(n)
    bar = tqdm(total=n, desc="pushes settled", unit="push", disable=not progress, leave=False)
    while active.size:
        batch.step(ids=active, nstep=chunk)
        speed = np.abs(qvel[active, bv : bv + 3]).max(axis=1)
        settled = (speed < settle_speed) | ~np.isfinite(speed)
        timed_out = now[active] >= max_time
        stop_time[active[settled]] = now[active[settled]]
        done = settled | timed_out
        bar.update(int(done.sum()))
        active = active[~done]
    bar.close()

    final = qpos[:, bq : bq + 7]
    disp = final[:, 0] - start[:, 0]
    lateral = final[:, 1] - start[:, 1]
    tilt, ok = push_checks(final, disp, lateral, stop_time, max_time)
    if not ok.all():
        log.warning("%d of %d pushes failed checks (unsettled, tipped, NaN or deflected)", int((~ok).sum()), n)
    return PushResult(displacement=disp, lateral=lateral, stop_time=stop_time, tilt=tilt, ok=ok)


def drive_stroke(
    batch: mjbatch.Batch,
    speeds: np.ndarray,
    *,
    stroke: float,
    max_time: float,
    push_qpos: int,
    push_dof: int,
    servo: int,
    after_step=None,
) -> None:
    """The pushing phase: command each push's speed until its pusher reaches the stroke.

    Simulations are stepped one substep at a time so that each stroke can end on the
    substep where the pusher reaches it; that substep's command is scaled to the
    fraction of it left, which keeps the displacement smooth in speed. The servo is
    then commanded zero (it brakes). ``after_step(ids)``, if given, runs after every
    substep with the simulations that took it (e.g. to record frames).
    """
    qpos, qvel, ctrl, now = batch.bind("qpos"), batch.bind("qvel"), batch.bind("ctrl"), batch.bind("time")
    dt = float(batch.model.opt.timestep)
    pushing = np.arange(batch.nsim)
    ctrl[:, :] = 0.0
    while pushing.size:
        # substeps of travel left in the stroke at the current pusher speed
        left = (stroke - qpos[pushing, push_qpos]) / np.maximum(qvel[pushing, push_dof] * dt, 1e-12)
        last = (left < 1.0) | (now[pushing] >= max_time)
        ctrl[pushing, servo] = np.where(last, np.clip(left, 0.0, 1.0), 1.0) * speeds[pushing]
        batch.step(ids=pushing, nstep=1)
        ctrl[pushing[last], servo] = 0.0
        if after_step is not None:
            after_step(pushing)
        pushing = pushing[~last]


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
