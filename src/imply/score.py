"""Implied physics and the self and anchored disagreement of sets of rollouts.

Definitions (all logs natural, displacements in metres, clamped below at the readout
floor so that a rollout in which nothing moves gives a large but finite score):

* A set has K rollouts (v_k, d_k) and optionally C observed calibration pushes
  (v^c_j, d^c_j), for the same object.
* Implied physics: the (m, mu) minimising sum_k (f(v_k, m, mu) - log d_k)^2, found by
  exhaustive search over an n x n grid in (log m, log mu) spanning the table's range
  (finer than the table), with f the table's cubic interpolant, then polished by a
  few Gauss-Newton steps (see :meth:`Scorer.fit`).
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
DEFAULT_GRID = 101


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

    def _rows_for(self, speeds: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """f and its derivatives in log m and log mu on the search grid, per distinct speed."""
        missing = [float(v) for v in speeds if float(v) not in self._rows]
        if missing:
            block = self.table.on_fine_grid(np.array(missing), self.grid)
            lm, lu = self.table.fine_axes(self.grid)
            for v, row in zip(missing, block, strict=True):
                sq = row.reshape(self.grid, self.grid)
                dm, du = np.gradient(sq, lm, lu)
                self._rows[v] = np.stack([row, dm.ravel(), du.ravel()])
        rows = np.stack([self._rows[float(v)] for v in speeds])
        return rows[:, 0], rows[:, 1], rows[:, 2]

    def fit(self, speeds, displacements) -> Fit:
        """Best single-object fit of each of N sets.

        speeds, displacements: (N, K) arrays (or (K,) speeds shared by all sets); NaN
        displacements are absent terms. Every set needs at least one term.

        The search is exhaustive on the grid, then a few Gauss-Newton steps from the best
        grid point (staying within a few grid cells and the table's range) are kept where
        they lower the exactly interpolated residual; this removes the grid's resolution
        from small residuals without giving up the global search.
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
        v_safe = np.where(present, v, self.table.speeds[0])

        n = d.shape[0]
        lm_axis, lu_axis = self.table.fine_axes(self.grid)
        theta = np.empty((n, 2))
        sse_best = np.empty(n)
        for lo in range(0, n, self.chunk):
            hi = min(lo + self.chunk, n)
            vc, yc, pc = v_safe[lo:hi], y[lo:hi], present[lo:hi]
            uniq, inv = np.unique(vc, return_inverse=True)
            idx = inv.reshape(vc.shape)
            f, dfm, dfu = self._rows_for(uniq)
            # per set and distinct speed: how many terms, and the sum of their log d
            rows = np.broadcast_to(np.arange(hi - lo)[:, None], vc.shape)
            weights = np.zeros((hi - lo, 2 * uniq.size))
            np.add.at(weights, (rows[pc], idx[pc]), 1.0)
            np.add.at(weights, (rows[pc], uniq.size + idx[pc]), -2.0 * yc[pc])
            # sum_k (f_k - y_k)^2 = sum_k f_k^2 - 2 y_k f_k + y_k^2; the last term is
            # constant per set, so the argmin needs one matrix product
            partial = weights @ np.concatenate([f * f, f])
            k = np.argmin(partial, axis=1)
            im, iu = np.divmod(k, self.grid)
            grid_theta = np.stack([lm_axis[im], lu_axis[iu]], axis=1)
            r = np.where(pc, f[idx, k[:, None]] - yc, 0.0)
            sse_grid = (r * r).sum(1)
            gn_theta, sse_gn = self._gauss_newton(vc, yc, pc, grid_theta, uniq, idx)
            better = sse_gn < sse_grid
            theta[lo:hi] = np.where(better[:, None], gn_theta, grid_theta)
            sse_best[lo:hi] = np.where(better, sse_gn, sse_grid)
        return Fit(
            rms=np.sqrt(np.maximum(sse_best, 0.0) / counts), mass=np.exp(theta[:, 0]), friction=np.exp(theta[:, 1])
        )

    def _gauss_newton(self, v, y, present, theta, uniq, idx, iterations: int = 3, max_cells: float = 3.0):
        """Gauss-Newton from the grid optimum: exact residuals, grid derivatives.

        Each step uses the derivatives at the grid point nearest the current estimate;
        the estimate stays within ``max_cells`` grid cells of where it started and inside
        the table's range. Returns the final estimates and their exact residual sums.
        """
        lm_axis, lu_axis = self.table.fine_axes(self.grid)
        cell = np.array([lm_axis[1] - lm_axis[0], lu_axis[1] - lu_axis[0]])
        lo = np.array([lm_axis[0], lu_axis[0]])
        hi = np.array([lm_axis[-1], lu_axis[-1]])
        _, dfm, dfu = self._rows_for(uniq)
        start = theta.copy()
        for _ in range(iterations):
            pred = self._predict(v, present, theta)
            r = np.where(present, pred - y, 0.0)
            near = np.clip(np.rint((theta - lo) / cell), 0, self.grid - 1).astype(np.int64)
            k = near[:, 0] * self.grid + near[:, 1]
            jm = np.where(present, dfm[idx, k[:, None]], 0.0)
            ju = np.where(present, dfu[idx, k[:, None]], 0.0)
            a11, a12, a22 = (jm * jm).sum(1), (jm * ju).sum(1), (ju * ju).sum(1)
            b1, b2 = (jm * r).sum(1), (ju * r).sum(1)
            det = a11 * a22 - a12 * a12
            ok = det > 1e-12 * np.maximum(a11 * a22, 1e-300)
            det = np.where(ok, det, 1.0)
            step = np.stack([-(a22 * b1 - a12 * b2) / det, -(a11 * b2 - a12 * b1) / det], axis=1)
            step[~ok] = 0.0
            theta = np.clip(np.clip(theta + step, start - max_cells * cell, start + max_cells * cell), lo, hi)
        pred = self._predict(v, present, theta)
        return theta, np.where(present, (pred - y) ** 2, 0.0).sum(1)

    def _predict(self, v: np.ndarray, present: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """Interpolated log d of each set's terms at that set's (log m, log mu)."""
        lm = np.broadcast_to(theta[:, :1], v.shape)
        lu = np.broadcast_to(theta[:, 1:], v.shape)
        pred = np.zeros(v.shape)
        pred[present] = self.table.log_displacement(v[present], np.exp(lm[present]), np.exp(lu[present]))
        return pred

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
