"""A timestep-to-zero reference for push displacements, on a plain code path of its own.

:mod:`imply.sim.pushes` earns its accuracy with a fine push step, a shortened last
step, a coarse slide and a travel correction; each is a place for a mistake. The
reference uses none of them: one uniform step from start to rest, the servo
switched to braking after the first step that reaches the stroke, and MuJoCo's own
positions. It converges at first order in the step, so running it at two steps h and
2h also estimates its own error (about the difference of the two).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from mujoco import batch as mjbatch
from tqdm.auto import tqdm

from imply.sim.scene import SceneConfig, build_model


@dataclass(frozen=True)
class ReferencePushes:
    """log displacements (n,) at a uniform step, and an estimate of their own error (n,)."""

    log_d: np.ndarray
    error_estimate: np.ndarray
    step: float


def uniform_step_log_d(
    speeds: np.ndarray,
    masses: np.ndarray,
    frictions: np.ndarray,
    *,
    scene: SceneConfig,
    step: float,
    nthread: int = 0,
    progress: bool = False,
) -> np.ndarray:
    """log displacement (n,) of pushes of the canonical box stepped at one uniform ``step`` (s)."""
    speeds, masses, frictions = (np.asarray(a, dtype=float).ravel() for a in (speeds, masses, frictions))
    # release_window and slide_steps do not apply here; push_substeps=1 keeps the step uniform
    model = build_model(replace(scene, timestep=step, push_substeps=1, release_window=0.0, slide_steps=0))
    n = speeds.size
    box = model.body("box").id
    bq = int(model.jnt_qposadr[model.joint("box").id])
    bv = int(model.jnt_dofadr[model.joint("box").id])
    pq = int(model.jnt_qposadr[model.joint("push").id])
    batch = mjbatch.Batch(model, n, nthread=nthread)
    batch.body("box").mass = masses[:, None]
    batch.body("box").inertia = model.body_inertia[box][None, :] * (masses / model.body_mass[box])[:, None]
    friction = np.tile(model.geom_friction[model.geom("box").id], (n, 1))
    friction[:, 0] = frictions
    batch.geom("box").friction = friction
    batch.set_const()
    batch.reset()
    qpos, qvel, ctrl, now = batch.bind("qpos"), batch.bind("qvel"), batch.bind("ctrl"), batch.bind("time")
    x0 = qpos[:, bq].copy()
    servo = model.actuator("servo").id
    ctrl[:, servo] = speeds
    pushing = np.arange(n)
    while pushing.size:
        batch.step(ids=pushing, nstep=1)
        reached = (qpos[pushing, pq] >= scene.stroke) | (now[pushing] >= scene.max_time)
        ctrl[pushing[reached], servo] = 0.0
        pushing = pushing[~reached]
    chunk = max(1, int(round(0.005 / step)))
    active = np.arange(n)
    bar = tqdm(total=n, desc=f"reference pushes at {step * 1e6:.4g} us", disable=not progress, leave=False)
    while active.size:
        batch.step(ids=active, nstep=chunk)
        speed = np.abs(qvel[active, bv : bv + 3]).max(axis=1)
        done = (speed < scene.settle_speed) | (now[active] >= scene.max_time) | ~np.isfinite(speed)
        bar.update(int(done.sum()))
        active = active[~done]
    bar.close()
    return np.log(qpos[:, bq] - x0)


def reference_log_d(
    speeds: np.ndarray,
    masses: np.ndarray,
    frictions: np.ndarray,
    *,
    scene: SceneConfig,
    step: float,
    nthread: int = 0,
    progress: bool = False,
) -> ReferencePushes:
    """Uniform-step log d at ``step``, with its error estimated from a second run at twice the step."""
    fine = uniform_step_log_d(speeds, masses, frictions, scene=scene, step=step, nthread=nthread, progress=progress)
    coarse = uniform_step_log_d(
        speeds, masses, frictions, scene=scene, step=2 * step, nthread=nthread, progress=progress
    )
    return ReferencePushes(log_d=fine, error_estimate=np.abs(fine - coarse), step=step)
