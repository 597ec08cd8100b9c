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
(all objects x all speeds), never a loop of single pushes. :func:`standin_rollouts` makes
the study's ``rollouts.csv`` (every stand-in's rollouts of the evaluation objects) and
:func:`rollout_arrays` reads it back.
"""

from __future__ import annotations

import logging

import numpy as np
import pandas as pd

from imply.study.section4.config import StandinsConfig
from imply.study.section4.objects import STREAM_JITTER, pivot, population, rng_for, simulate_grid, sizes, truth_arrays
from imply.table import PushTable

log = logging.getLogger("imply.section4")

STANDINS: tuple[str, ...] = ("oracle", "jitter", "blind", "collapse")


def oracle(speeds, masses, frictions, half_extents, **sim_kwargs) -> tuple[np.ndarray, np.ndarray]:
    """Oracle rollouts: the simulator with each object's true physics and geometry."""
    return simulate_grid(speeds, masses, frictions, half_extents, **sim_kwargs)


def jitter_physics(
    masses,
    frictions,
    *,
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
    m, mu = jitter_physics(
        masses, frictions, k=k, draws=draws, sd=sd, rng=rng, mass_range=mass_range, friction_range=friction_range
    )
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


def standin_rollouts(
    objects: pd.DataFrame,
    truth: pd.DataFrame,
    *,
    settings: StandinsConfig,
    seed: int,
    table: PushTable,
    query_speeds,
    calibration_speeds,
    floor: float,
    **sim_kwargs,
) -> pd.DataFrame:
    """Rollouts of every stand-in, long format: object_id, standin, draw, speed, displacement.

    Jitter has ``settings.jitter_draws`` independent rollout sets per object (draw 0 is
    the one scored in Table 1; the selection study uses further draws so two jitter
    candidates of one object differ); the others have one.
    """
    t = truth_arrays(truth, query_speeds=query_speeds, calibration_speeds=calibration_speeds)
    ev = population(objects, "eval").set_index("object_id").loc[t["ids"]]
    n, k = t["query"].shape
    q = t["query_speeds"]
    jit, jok, _, _ = jitter(
        q,
        ev["mass"].to_numpy(float),
        ev["friction"].to_numpy(float),
        sizes(ev),
        sd=settings.jitter_sd,
        draws=settings.jitter_draws,
        rng=rng_for(seed, STREAM_JITTER),
        mass_range=table.mass_range,
        friction_range=table.friction_range,
        **sim_kwargs,
    )
    if not jok.all():
        log.warning("%d jitter pushes failed the simulator's checks; kept as simulated", int((~jok).sum()))
    sets = {
        # the oracle's rollouts are the true query pushes (same simulator, physics, geometry)
        "oracle": t["query"][:, None, :],
        "jitter": jit,
        "blind": object_blind(n, typical_displacement(t["train"]))[:, None, :],
        "collapse": collapse(n, k, floor)[:, None, :],
    }
    frames = []
    for name in STANDINS:
        arr = sets[name]
        nd = arr.shape[1]
        frames.append(
            pd.DataFrame(
                {
                    "object_id": np.repeat(t["ids"], nd * k),
                    "standin": name,
                    "draw": np.tile(np.repeat(np.arange(nd), k), n),
                    "speed": np.tile(q, n * nd),
                    "displacement": arr.ravel(),
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def rollout_arrays(rollouts: pd.DataFrame, ids: list[str], speeds) -> dict[str, np.ndarray]:
    """Stand-in rollouts as arrays: name -> (N, draws, K) in the given object order."""
    speeds = np.asarray(speeds, dtype=float)
    out = {}
    for name in STANDINS:
        sub = rollouts[rollouts["standin"] == name]
        if sub.empty:
            raise ValueError(f"rollouts have no {name!r} stand-in")
        nd = int(sub["draw"].max()) + 1
        out[name] = np.stack([pivot(sub[sub["draw"] == j], ids, speeds, f"{name} draw {j}") for j in range(nd)], 1)
    return out
