"""Mass and friction are identifiable from pushes at the five query speeds."""

from __future__ import annotations

import numpy as np

from imply.score import Scorer
from imply.sim import simulate_pushes


def r_squared(truth: np.ndarray, estimate: np.ndarray) -> float:
    return 1.0 - np.sum((truth - estimate) ** 2) / np.sum((truth - truth.mean()) ** 2)


def test_grid_inversion_recovers_log_mass_and_log_friction(full_table, scene, default_config):
    rng = np.random.default_rng(12345)
    n = 200
    lo_m, hi_m = full_table.mass_range
    lo_u, hi_u = full_table.friction_range
    log_m = rng.uniform(np.log(lo_m), np.log(hi_m), n)
    log_u = rng.uniform(np.log(lo_u), np.log(hi_u), n)
    speeds = np.array(default_config["score"]["query_speeds"])
    res = simulate_pushes(
        np.tile(speeds, n),
        np.repeat(np.exp(log_m), speeds.size),
        np.repeat(np.exp(log_u), speeds.size),
        scene=scene,
        nthread=2,
    )
    assert res.ok.all()
    fit = Scorer(full_table, grid=default_config["score"]["grid"]).fit(speeds, res.displacement.reshape(n, -1))
    r2_mass = r_squared(log_m, np.log(fit.mass))
    r2_friction = r_squared(log_u, np.log(fit.friction))
    print(f"R^2 log mass {r2_mass:.3f}, log friction {r2_friction:.3f}")
    assert r2_mass >= 0.95
    assert r2_friction >= 0.95
