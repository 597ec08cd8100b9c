"""Implied physics and the self and anchored disagreement of sets of rollouts.

Definitions (all logs natural, displacements in metres, clamped below at the readout
floor so that a rollout in which nothing moves gives a large but finite score):

* A set has K rollouts (v_k, d_k) and optionally C observed calibration pushes
  (v^c_j, d^c_j), for the same object.
* Implied physics: the (m, mu) minimising sum_k (f(v_k, m, mu) - log d_k)^2, found by
  exhaustive search over an n x n grid in (log m, log mu) spanning the table's range,
  with f the table's cubic interpolant.
* Self-disagreement: sqrt(min over (m, mu) of that sum / K), the RMS log residual of
  the single object that best explains the rollouts alone.
* Anchored disagreement: sqrt(min over (m, mu) of [sum_j (f(v^c_j, m, mu) - log d^c_j)^2
  + sum_k (f(v_k, m, mu) - log d_k)^2] / (C + K)), the RMS log residual of the single
  object that explains the calibration pushes and the rollouts together.

Sets may be ragged: a NaN displacement marks an absent term. The sum of squares for
all grid points is a product of small matrices, (count, weighted log d) per distinct
speed against the grid's f and f^2, so scoring is a few matrix products per chunk of
sets rather than an optimiser per set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imply.table import PushTable

DEFAULT_FLOOR = 1e-4
DEFAULT_GRID = 161


@dataclass(frozen=True)
class Fit:
    """Best single-object fits of N sets: (N,) arrays."""

    rms: np.ndarray
    mass: np.ndarray
    friction: np.ndarray


@dataclass(frozen=True)
class Scores:
    """Scores of N sets of rollouts: (N,) arrays (anchored ones NaN without calibration)."""

    n_rollouts: np.ndarray
    self_disagreement: np.ndarray
    anchored_disagreement: np.ndarray
    mass_hat: np.ndarray
    friction_hat: np.ndarray
    anchored_mass_hat: np.ndarray
    anchored_friction_hat: np.ndarray


class Scorer:
    """Scores sets against one table; caches the table on the search grid per speed."""

    def __init__(self, table: PushTable, grid: int = DEFAULT_GRID, floor: float = DEFAULT_FLOOR, chunk: int = 1024):
        if grid < 2:
            raise ValueError("grid must have at least 2 points per axis")
        if not floor > 0:
            raise ValueError("readout floor must be positive")
        self.table = table
        self.grid = grid
        self.floor = floor
        self.chunk = chunk
        self._rows: dict[float, np.ndarray] = {}
        lm, lu = table.fine_axes(grid)
        self.grid_mass = np.exp(np.repeat(lm, grid))
        self.grid_friction = np.exp(np.tile(lu, grid))

    def _f(self, speeds: np.ndarray) -> np.ndarray:
        """Rows of f on the search grid for the given distinct speeds: (len, grid^2)."""
        missing = [float(v) for v in speeds if float(v) not in self._rows]
        if missing:
            block = self.table.on_fine_grid(np.array(missing), self.grid)
            for v, row in zip(missing, block):
                self._rows[v] = row
        return np.stack([self._rows[float(v)] for v in speeds])

    def fit(self, speeds, displacements) -> Fit:
        """Best single-object fit of each of N sets.

        speeds, displacements: (N, K) arrays (or (K,) speeds shared by all sets); NaN
        displacements are absent terms. Every set needs at least one term.
        """
        d = np.atleast_2d(np.asarray(displacements, dtype=float))
        v = np.broadcast_to(np.asarray(speeds, dtype=float), d.shape)
        present = np.isfinite(d)
        if np.any(present & ~np.isfinite(v)):
            raise ValueError("a present term has a non-finite speed")
        if np.any(d[present] < 0):
            raise ValueError("displacements must be non-negative")
        counts = present.sum(axis=1)
        if np.any(counts == 0):
            raise ValueError(f"set {int(np.flatnonzero(counts == 0)[0])} has no terms")
        self.table.check_range(speeds=v[present])
        y = np.where(present, np.log(np.maximum(np.where(present, d, 1.0), self.floor)), 0.0)

        n = d.shape[0]
        rms = np.empty(n)
        best = np.empty(n, dtype=np.int64)
        for lo in range(0, n, self.chunk):
            hi = min(lo + self.chunk, n)
            vc, yc, pc = v[lo:hi], y[lo:hi], present[lo:hi]
            uniq, inv = np.unique(np.where(pc, vc, np.nan)[pc], return_inverse=True)
            idx = np.zeros(vc.shape, dtype=np.int64)
            idx[pc] = inv
            f = self._f(uniq)
            # per set and distinct speed: how many terms, and the sum of their log d
            count = np.zeros((hi - lo, uniq.size))
            ysum = np.zeros((hi - lo, uniq.size))
            rows = np.repeat(np.arange(hi - lo), vc.shape[1]).reshape(vc.shape)
            np.add.at(count, (rows[pc], idx[pc]), 1.0)
            np.add.at(ysum, (rows[pc], idx[pc]), yc[pc])
            sse = count @ (f * f) - 2.0 * (ysum @ f) + (yc * yc).sum(axis=1, keepdims=True)
            k = np.argmin(sse, axis=1)
            best[lo:hi] = k
            rms[lo:hi] = np.sqrt(np.maximum(sse[np.arange(hi - lo), k], 0.0) / counts[lo:hi])
        return Fit(rms=rms, mass=self.grid_mass[best], friction=self.grid_friction[best])

    def score(self, speeds, displacements, calib_speeds=None, calib_displacements=None) -> Scores:
        """Self and anchored disagreement of N sets (see the module docstring).

        speeds, displacements: (N, K) rollouts (NaN displacement: absent).
        calib_speeds, calib_displacements: (N, C) observed calibration pushes, or None.
        """
        d = np.atleast_2d(np.asarray(displacements, dtype=float))
        v = np.broadcast_to(np.asarray(speeds, dtype=float), d.shape)
        selfit = self.fit(v, d)
        n = d.shape[0]
        nan = np.full(n, np.nan)
        anch = Fit(nan, nan, nan)
        if calib_displacements is not None:
            cd = np.atleast_2d(np.asarray(calib_displacements, dtype=float))
            cd = np.broadcast_to(cd, (n, cd.shape[1]))
            cv = np.broadcast_to(np.asarray(calib_speeds, dtype=float), cd.shape)
            anch = self.fit(np.concatenate([cv, v], axis=1), np.concatenate([cd, d], axis=1))
        return Scores(
            n_rollouts=np.isfinite(d).sum(axis=1),
            self_disagreement=selfit.rms,
            anchored_disagreement=anch.rms,
            mass_hat=selfit.mass,
            friction_hat=selfit.friction,
            anchored_mass_hat=anch.mass,
            anchored_friction_hat=anch.friction,
        )


def score_sets(
    table: PushTable,
    speeds,
    displacements,
    calib_speeds=None,
    calib_displacements=None,
    *,
    grid: int = DEFAULT_GRID,
    floor: float = DEFAULT_FLOOR,
) -> Scores:
    """One-shot :meth:`Scorer.score`."""
    return Scorer(table, grid=grid, floor=floor).score(speeds, displacements, calib_speeds, calib_displacements)
