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

import contextlib
import functools
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from typing import TYPE_CHECKING, ClassVar

import numpy as np

from imply.options import Config, option

if TYPE_CHECKING:
    from imply.table import PushTable

DEFAULT_FLOOR = 1e-4
DEFAULT_GRID = 101


@dataclass(frozen=True, kw_only=True)
class ScoreConfig(Config):
    """Config section ``score``: the search grid, the readout floor (m), and the study's push speeds (m/s).

    A rule passes only the keys it reads; the others keep these defaults.
    """

    config_key: ClassVar[str] = "score"

    grid: int = option(DEFAULT_GRID, doc="search grid points per axis", minimum=11, required=True)
    readout_floor: float = option(DEFAULT_FLOOR, doc="readout floor (m)", exclusive_minimum=0, required=True)
    query_speeds: tuple[float, ...] = option(
        (0.25, 0.4, 0.55, 0.7, 0.85),
        doc="query push speeds (m/s)",
        required=True,
        min_items=2,
        unique=True,
        items={"exclusive_minimum": 0},
    )
    calibration_speeds: tuple[float, ...] = option(
        (0.3, 0.8),
        doc="the two calibration push speeds (m/s)",
        required=True,
        min_items=2,
        max_items=2,
        unique=True,
        items={"exclusive_minimum": 0},
    )

    def __post_init__(self) -> None:
        if self.grid < 2:
            raise ValueError(f"grid must have at least 2 points per axis, not {self.grid}")
        if not self.readout_floor > 0:
            raise ValueError("readout_floor must be positive")
        if len(self.query_speeds) < 2 or len(self.calibration_speeds) != 2:
            raise ValueError("need at least 2 query speeds and exactly 2 calibration speeds")

    def scorer(self, table: PushTable) -> Scorer:
        """A :class:`Scorer` of ``table`` with this grid and readout floor."""
        return Scorer(table, grid=self.grid, floor=self.readout_floor)


@functools.cache
def _blas_controller():
    try:
        from threadpoolctl import ThreadpoolController
    except ImportError:
        return None
    return ThreadpoolController()


def one_blas_thread() -> contextlib.AbstractContextManager:
    """Run BLAS on one thread inside the block (the whole process: enter it once, not per thread).

    The grid search is many small products; on two BLAS threads each one waits for the
    other, and when another process holds a core that wait made scoring up to ten
    times slower (measured), for no gain on an idle machine. Scorer(threads=...) fits
    chunks of sets side by side instead.
    """
    controller = _blas_controller()
    return controller.limit(limits=1, user_api="blas") if controller is not None else contextlib.nullcontext()


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

    def __init__(
        self,
        table: PushTable,
        *,
        grid: int = DEFAULT_GRID,
        floor: float = DEFAULT_FLOOR,
        chunk: int = 1024,
        block_bytes: int = 2 << 20,
        threads: int = 1,
    ):
        """``threads`` chunks of sets are fitted at once (each with single-threaded BLAS)."""
        if grid < 2:
            raise ValueError("grid must have at least 2 points per axis")
        if not floor > 0:
            raise ValueError("readout floor must be positive")
        self.table = table
        self.grid = grid
        self.floor = floor
        self.chunk = chunk
        self.block_bytes = block_bytes
        self.threads = max(1, int(threads))
        self._rows: dict[float, np.ndarray] = {}
        self._slice_cache: dict[float, np.ndarray] = {}
        lm, lu = table.fine_axes(grid)
        self.grid_mass = np.exp(np.repeat(lm, grid))
        self.grid_friction = np.exp(np.tile(lu, grid))

    def _rows_for(self, speeds: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """f and its derivatives in log m and log mu on the search grid, per distinct speed."""
        self._cache_rows(speeds)
        rows = np.stack([self._rows[float(v)] for v in speeds])
        return rows[:, 0], rows[:, 1], rows[:, 2]

    def _cache_rows(self, speeds: np.ndarray) -> None:
        missing = [float(v) for v in speeds if float(v) not in self._rows]
        if missing:
            block = self.table.on_fine_grid(np.array(missing), self.grid)
            lm, lu = self.table.fine_axes(self.grid)
            for v, row in zip(missing, block, strict=True):
                sq = row.reshape(self.grid, self.grid)
                dm, du = np.gradient(sq, lm, lu)
                self._rows[v] = np.stack([row, dm.ravel(), du.ravel()])

    def _slices(self, uniq: np.ndarray):
        """The table's spline restricted to each distinct speed, as one evaluable spline.

        The table's cubic spline in (v, log m, log mu) is contracted with the speed basis
        at each speed in ``uniq``, leaving a bicubic spline per speed (a quarter of the
        work per point); a degree-0 first axis selects the slice, so term j of speed
        ``uniq[i]`` evaluates at (i + 0.5, log m, log mu). Values agree with the table's
        own interpolation to rounding (about 1e-15). None where scipy keeps no spline
        object, and the table is evaluated directly.
        """
        from scipy.interpolate import NdBSpline

        spline = self._table_spline()
        if spline is None:
            return None
        self._cache_slices(uniq)
        coefs = np.stack([self._slice_cache[float(v)] for v in uniq])
        knots = (np.arange(uniq.size + 1, dtype=float), spline.t[1], spline.t[2])
        return NdBSpline(knots, coefs, k=(0, int(spline.k[1]), int(spline.k[2])))

    def _table_spline(self):
        from scipy.interpolate import NdBSpline

        spline = getattr(self.table._interpolator, "_spline", None)
        return spline if isinstance(spline, NdBSpline) and len(spline.t) == 3 else None

    def _cache_slices(self, speeds: np.ndarray) -> None:
        from scipy.interpolate import BSpline

        spline = self._table_spline()
        missing = [float(v) for v in speeds if float(v) not in self._slice_cache]
        if spline is None or not missing:
            return
        basis = BSpline.design_matrix(np.array(missing), spline.t[0], int(spline.k[0])).toarray()
        for v, c in zip(missing, np.tensordot(basis, spline.c, axes=(1, 0)), strict=True):
            self._slice_cache[v] = c

    def _grid_argmin(self, counts: np.ndarray, sums: np.ndarray, f: np.ndarray) -> np.ndarray:
        """Index of the grid point with the least sum of squares, per set.

        counts, sums: (sets, distinct speeds) number of terms and -2 sum of log d per speed;
        f: (distinct speeds, grid points). Up to a constant per set, the sum of squares is
        counts @ f^2 + sums @ f. Sets share few count patterns (usually one per role
        layout), so counts @ f^2 is formed once per pattern and picked by a one-hot
        column, which shortens the product. The (sets x grid points) sums are formed a
        cache-sized block of sets at a time into one reused buffer: the whole product
        would be written to and read back from memory, which took most of the scoring
        time, and its size grows with grid^2.
        """
        # rows as single opaque values: a 1-D unique is much cheaper than unique(axis=0)
        rows = np.ascontiguousarray(counts)
        keys = rows.view(np.dtype((np.void, rows.dtype.itemsize * rows.shape[1]))).ravel()
        _, first, which = np.unique(keys, return_index=True, return_inverse=True)
        patterns = rows[first]
        if patterns.shape[0] <= counts.shape[1]:
            weights = np.concatenate([sums, np.eye(patterns.shape[0])[which.ravel()]], axis=1)
            basis = np.concatenate([f, patterns @ (f * f)])
        else:
            weights = np.concatenate([counts, sums], axis=1)
            basis = np.concatenate([f * f, f])
        n_points = basis.shape[1]
        block = max(1, self.block_bytes // (8 * n_points))
        buf = np.empty((min(block, weights.shape[0]), n_points))
        best = np.empty(weights.shape[0], dtype=np.int64)
        for lo in range(0, weights.shape[0], block):
            hi = min(lo + block, weights.shape[0])
            out = buf[: hi - lo]
            np.matmul(weights[lo:hi], basis, out=out)
            best[lo:hi] = np.argmin(out, axis=1)
        return best

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
        theta = np.empty((n, 2))
        sse_best = np.empty(n)
        # fill the per-speed caches first: the chunks then only read them, from any thread
        every_speed = np.unique(v_safe[present])
        self._cache_rows(every_speed)
        self._cache_slices(every_speed)

        def one_chunk(lo: int) -> None:
            hi = min(lo + self.chunk, n)
            theta[lo:hi], sse_best[lo:hi] = self._fit_chunk(v_safe[lo:hi], y[lo:hi], present[lo:hi])

        starts = range(0, n, self.chunk)
        workers = min(self.threads, len(starts))
        with one_blas_thread():
            if workers > 1:
                with ThreadPoolExecutor(workers) as pool:
                    list(pool.map(one_chunk, starts))
            else:
                for lo in starts:
                    one_chunk(lo)
        return Fit(
            rms=np.sqrt(np.maximum(sse_best, 0.0) / counts), mass=np.exp(theta[:, 0]), friction=np.exp(theta[:, 1])
        )

    def _fit_chunk(self, vc: np.ndarray, yc: np.ndarray, pc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Best (log m, log mu) and residual sum of squares of one chunk of sets (see :meth:`fit`)."""
        lm_axis, lu_axis = self.table.fine_axes(self.grid)
        m = vc.shape[0]
        uniq, inv = np.unique(vc, return_inverse=True)
        idx = inv.reshape(vc.shape)
        f, _, _ = self._rows_for(uniq)
        # per set and distinct speed: how many terms, and the sum of their log d
        rows = np.broadcast_to(np.arange(m)[:, None], vc.shape)
        per_speed = np.zeros((m, uniq.size))
        sums = np.zeros((m, uniq.size))
        np.add.at(per_speed, (rows[pc], idx[pc]), 1.0)
        np.add.at(sums, (rows[pc], idx[pc]), -2.0 * yc[pc])
        # sum_k (f_k - y_k)^2 = sum_k f_k^2 - 2 y_k f_k + y_k^2; the last term is
        # constant per set, so the argmin needs one matrix product
        k = self._grid_argmin(per_speed, sums, f)
        im, iu = np.divmod(k, self.grid)
        grid_theta = np.stack([lm_axis[im], lu_axis[iu]], axis=1)
        at_grid = f[idx, k[:, None]]
        r = np.where(pc, at_grid - yc, 0.0)
        sse_grid = (r * r).sum(1)
        gn_theta, sse_gn = self._gauss_newton(uniq, idx, yc, pc, grid_theta, at_grid)
        better = sse_gn < sse_grid
        return np.where(better[:, None], gn_theta, grid_theta), np.where(better, sse_gn, sse_grid)

    def _gauss_newton(self, uniq, idx, y, present, theta, at_start, iterations: int = 3, max_cells: float = 3.0):
        """Gauss-Newton from the grid optimum: exact residuals, grid derivatives.

        ``idx`` holds each term's index into the distinct speeds ``uniq``; ``at_start``
        is the interpolated log d of each term at the starting grid points (the search
        has it). Each step uses the derivatives at the grid point nearest the current
        estimate; the estimate stays within ``max_cells`` grid cells of where it started
        and inside the table's range. Returns the final estimates and their exact
        residual sums.
        """
        lm_axis, lu_axis = self.table.fine_axes(self.grid)
        cell = np.array([lm_axis[1] - lm_axis[0], lu_axis[1] - lu_axis[0]])
        lo = np.array([lm_axis[0], lu_axis[0]])
        hi = np.array([lm_axis[-1], lu_axis[-1]])
        _, dfm, dfu = self._rows_for(uniq)
        slices = self._slices(uniq)
        start = theta.copy()
        for i in range(iterations):
            pred = at_start if i == 0 else self._predict(uniq, idx, present, theta, slices)
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
        pred = self._predict(uniq, idx, present, theta, slices)
        return theta, np.where(present, (pred - y) ** 2, 0.0).sum(1)

    def _predict(self, uniq, idx, present, theta, slices) -> np.ndarray:
        """Interpolated log d of each set's terms at that set's (log m, log mu)."""
        lm = np.broadcast_to(theta[:, :1], idx.shape)[present]
        lu = np.broadcast_to(theta[:, 1:], idx.shape)[present]
        pred = np.zeros(idx.shape)
        if slices is None:
            pred[present] = self.table.log_displacement(uniq[idx[present]], np.exp(lm), np.exp(lu))
        else:
            pred[present] = slices(np.column_stack([idx[present] + 0.5, lm, lu]))
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
