"""The world's own numerical error, measured rather than assumed.

A sample of the benchmark's own pushes (effects and all) is simulated again with every
step four times finer (:meth:`~imply.realworld.world.WorldStepping.finer`); the
difference is the error of the world's stepping (RK4 converges at fourth order away
from contact events, so the finer run is far closer to the limit). Pushes of the
nominal world are also compared with :mod:`imply.sim.reference`, the project's plain
uniform-step Euler reference (its own error estimated from a run at twice its step), a
code path that shares nothing with the world's but the scene. The benchmark records
both beside the table's measured error (its metadata's ``numerical_error``): the world
must be at least as close to the timestep-to-zero limit as the table is.
"""

from __future__ import annotations

import numpy as np

from imply.realworld.world import WorldPushes, WorldStepping, simulate_world
from imply.sim.reference import reference_log_d
from imply.sim.scene import SceneConfig


def _summary(diff: np.ndarray) -> dict:
    diff = diff[np.isfinite(diff)]
    if not diff.size:
        return {"n": 0, "max_abs": None, "rms": None}
    return {"n": int(diff.size), "max_abs": float(np.abs(diff).max()), "rms": float(np.sqrt(np.mean(diff**2)))}


def worst_push(pushes: WorldPushes, d: np.ndarray, t: np.ndarray, scene: SceneConfig) -> dict | None:
    """The push of ``pushes`` whose log d differs most from its finer run (``d``, ``t``: (n,) log d and log stop-time
    differences, NaN where either run failed): its conditions and every world parameter away from the nominal
    world's of ``scene``, so that it can be simulated again alone; None where no push compares."""
    if not np.isfinite(d).any():
        return None
    i = int(np.nanargmax(np.abs(d)))
    nominal = WorldPushes.nominal(pushes.speed[i], pushes.mass[i], pushes.friction[i], pushes.direction[i], scene)
    changed = {
        name: float(values[i])
        for name, values in pushes.params.items()
        if not np.isclose(values[i], nominal.params[name][0], rtol=0.0, atol=1e-12)
    }
    return {
        "index": i,
        "log_d_difference": float(d[i]),
        "log_stop_time_difference": float(t[i]) if np.isfinite(t[i]) else None,
        "speed": float(pushes.speed[i]),
        "mass": float(pushes.mass[i]),
        "friction": float(pushes.friction[i]),
        "direction": float(pushes.direction[i]),
        "parameters": changed,
    }


def measure_error(
    pushes: WorldPushes,
    nominal: WorldPushes,
    scene: SceneConfig,
    stepping: WorldStepping,
    *,
    factor: int = 4,
    reference_step: float = 1.5625e-5,
    nthread: int = 0,
    progress: bool = False,
) -> dict:
    """Error of the world's log d and log stop time on ``pushes`` (against the same pushes
    ``factor`` times finer) and on ``nominal`` pushes (also against :mod:`imply.sim.reference`)."""
    both = WorldPushes.concat([pushes, nominal])
    run = simulate_world(both, scene, stepping, nthread=nthread, progress=progress)
    fine = simulate_world(both, scene, stepping.finer(factor), nthread=nthread, progress=progress)
    ok = run.ok & fine.ok
    d = np.where(ok, np.log(run.displacement) - np.log(fine.displacement), np.nan)
    t = np.where(ok, np.log(run.stop_time) - np.log(fine.stop_time), np.nan)
    n = pushes.n
    ref = reference_log_d(
        nominal.speed,
        nominal.mass,
        nominal.friction,
        scene=scene,
        step=reference_step,
        nthread=nthread,
        progress=progress,
    )
    d_ref = np.where(run.ok[n:], np.log(run.displacement[n:]) - ref.log_d, np.nan)
    return {
        "against_finer": {
            "factor": factor,
            "log_d": _summary(d),
            "log_stop_time": _summary(t),
            "failed": int((~ok).sum()),
            "worst": worst_push(both, d, t, scene),
            "method": (
                f"{both.n} pushes ({n} drawn from the benchmark's logs, effects included, and {nominal.n} of the "
                f"nominal world) simulated again with every step {factor} times finer"
            ),
        },
        "against_reference": {
            "log_d": _summary(d_ref),
            "reference_step_s": reference_step,
            "reference_error_max": float(ref.error_estimate.max()),
            "reference_error_rms": float(np.sqrt(np.mean(ref.error_estimate**2))),
            "method": (
                f"{nominal.n} pushes of the nominal world against imply.sim.reference (semi-implicit Euler, one "
                f"uniform step of {reference_step * 1e6:.4g} us from start to rest); the reference's own error is "
                "its difference from a run at twice its step"
            ),
        },
    }
