"""The four stand-in world models of the controlled validation (paper Section 4).

Each stand-in answers "push this object at speeds v_1..v_K: how far does it slide?"
with one displacement per speed (metres), for many objects at once:

* **oracle** -- the simulator with the object's true mass, friction and box geometry.
  Its rollouts are the truth, so its log error is zero by construction; its
  disagreement is not, because the score's table is built with the canonical box.
* **jitter** -- the simulator with the true geometry, but each rollout draws its own
  (m, mu), each perturbed log-normally (sd ``jitter_sd``) around the truth and clipped
  to the table's range (the simulator is only checked there). A model with no stable
  world in its head.
* **object-blind** -- the dataset-typical displacement for the speed, whatever the
  object: the geometric mean (exp of the mean log) of a separate population of
  training objects' true displacements at that speed. The pattern-matcher.
* **collapse** -- nothing moves: every displacement is the readout floor.

Every simulation goes through :func:`imply.sim.simulate_pushes` in one batch per call
(all objects x all speeds), never a loop of single pushes.
"""

from __future__ import annotations

import numpy as np

from imply.sim import SceneConfig, simulate_pushes

STANDINS: tuple[str, ...] = ("oracle", "jitter", "blind", "collapse")
LABELS: dict[str, str] = {
    "oracle": "Oracle (true physics)",
    "jitter": "Jitter (no stable world)",
    "blind": "Object-blind (typical slide)",
    "collapse": "Collapse (never moves)",
}


def simulate_grid(
    speeds,
    masses,
    frictions,
    half_extents,
    *,
    scene: SceneConfig | None = None,
    nthread: int = 0,
    progress: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Push every object at every speed in one batched simulation.

    Args:
      speeds: (K,) speeds shared by all objects, or (N, K) per object.
      masses, frictions: (N,) or (N, K) -- per object, or per (object, speed).
      half_extents: (N, 3) box half-extents per object.
    Returns:
      displacement (N, K) in metres and ok (N, K), the simulator's own checks.
    """
    masses = np.asarray(masses, dtype=float)
    n = masses.shape[0]
    speeds = np.asarray(speeds, dtype=float)
    k = speeds.shape[-1]
    v = np.broadcast_to(speeds, (n, k))
    m = np.broadcast_to(masses.reshape(n, -1), (n, k))
    mu = np.broadcast_to(np.asarray(frictions, dtype=float).reshape(n, -1), (n, k))
    he = np.broadcast_to(np.asarray(half_extents, dtype=float)[:, None, :], (n, k, 3))
    res = simulate_pushes(
        v.ravel(), m.ravel(), mu.ravel(), he.reshape(-1, 3), scene=scene, nthread=nthread, progress=progress
    )
    return res.displacement.reshape(n, k), res.ok.reshape(n, k)


def oracle(speeds, masses, frictions, half_extents, **sim_kwargs) -> tuple[np.ndarray, np.ndarray]:
    """Oracle rollouts: the simulator with each object's true physics and geometry."""
    return simulate_grid(speeds, masses, frictions, half_extents, **sim_kwargs)


def jitter_physics(
    masses,
    frictions,
    k: int,
    draws: int,
    sd: float,
    rng: np.random.Generator,
    mass_range: tuple[float, float],
    friction_range: tuple[float, float],
) -> tuple[np.ndarray, np.ndarray]:
    """Per-rollout (m, mu) of the jitter model: (N, draws, K) each, clipped to the ranges."""
    masses = np.asarray(masses, dtype=float)
    frictions = np.asarray(frictions, dtype=float)
    n = masses.size
    z = rng.standard_normal((2, n, draws, k))
    m = np.clip(masses[:, None, None] * np.exp(sd * z[0]), *mass_range)
    mu = np.clip(frictions[:, None, None] * np.exp(sd * z[1]), *friction_range)
    return m, mu


def jitter(
    speeds,
    masses,
    frictions,
    half_extents,
    *,
    sd: float,
    draws: int,
    rng: np.random.Generator,
    mass_range: tuple[float, float],
    friction_range: tuple[float, float],
    **sim_kwargs,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Jitter rollouts: ``draws`` independent rollout sets per object, one batch in all.

    Returns displacement (N, draws, K), ok (N, draws, K), and the drawn masses and
    frictions (N, draws, K).
    """
    speeds = np.asarray(speeds, dtype=float)
    k = speeds.size
    half_extents = np.asarray(half_extents, dtype=float)
    n = half_extents.shape[0]
    m, mu = jitter_physics(masses, frictions, k, draws, sd, rng, mass_range, friction_range)
    he = np.repeat(half_extents, draws, axis=0)
    disp, ok = simulate_grid(speeds, m.reshape(n * draws, k), mu.reshape(n * draws, k), he, **sim_kwargs)
    return disp.reshape(n, draws, k), ok.reshape(n, draws, k), m, mu


def typical_displacement(train_displacements) -> np.ndarray:
    """Dataset-typical displacement per speed: exp(mean log d) over training objects, (K,)."""
    d = np.asarray(train_displacements, dtype=float)
    if d.ndim != 2 or d.shape[0] == 0:
        raise ValueError("training displacements must be a non-empty (M, K) array")
    if np.any(~(d > 0)):
        raise ValueError("training displacements must be positive")
    return np.exp(np.log(d).mean(axis=0))


def object_blind(n: int, typical) -> np.ndarray:
    """Object-blind rollouts: the typical displacement for each speed, for every object: (N, K)."""
    typical = np.asarray(typical, dtype=float)
    return np.broadcast_to(typical, (n, typical.size)).copy()


def collapse(n: int, k: int, floor: float) -> np.ndarray:
    """Collapse rollouts: nothing moves, so every reading sits at the readout floor: (N, K)."""
    return np.full((n, k), float(floor))


def add_readout_noise(displacements, sd: float, z) -> np.ndarray:
    """Multiplicative log-normal readout noise: d * exp(sd * z), z standard normal draws."""
    return np.asarray(displacements, dtype=float) * np.exp(sd * np.asarray(z, dtype=float))
