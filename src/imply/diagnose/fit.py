"""Per-object (m, mu) fits of a push log under the baseline or an effect-augmented model.

The prediction for push p of object i is log d = f(v_p, m_i, mu_i) for the baseline
table f, or that plus an effect (:mod:`imply.sim.effects`): the coarse Delta table of a
``model`` effect at the push's direction-modulated level, or f at the actual speed
(``speed`` effects) or friction (``friction`` effects). Each object's (log m, log mu) is
started from :meth:`imply.score.Scorer.fit` on the baseline table (measured masses or
frictions in the log replace the fitted ones and stay fixed) and refined by
Levenberg-Marquardt steps, vectorised over objects (2 x 2 normal equations per
object, finite-difference Jacobian), inside the table's range. A global effect
magnitude is profiled: fitted at each point of a grid of magnitudes with every object's
(m, mu) refitted, warm-started from the neighbouring magnitude.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imply.diagnose.effect_tables import EffectTables
from imply.diagnose.pushlog import PushLog
from imply.score import Scorer
from imply.sim.effects import (
    FRICTION,
    MODEL,
    SPEED,
    Effect,
    transform_friction,
    transform_speed,
)
from imply.table import PushTable

_H = 1e-4  # finite-difference step in log m and log mu


@dataclass
class ObjectFit:
    """Per-object fit: (N,) log mass, log friction and sum of squared log residuals."""

    lm: np.ndarray
    lu: np.ndarray
    sse: np.ndarray


class Problem:
    """A push log against a baseline table and its effect tables."""

    def __init__(
        self,
        pushlog: PushLog,
        table: PushTable,
        etables: EffectTables | None,
        grid: int = 101,
        use_measured: bool = True,
    ):
        self.log = pushlog
        self.table = table
        self.etables = etables
        self.grid = grid
        self.v = pushlog.speed
        self.phi = pushlog.direction
        self.obj = pushlog.obj
        self.y = pushlog.log_d
        self.n_obj = len(pushlog.objects)
        self.counts = np.bincount(self.obj, minlength=self.n_obj).astype(float)
        self.lm_range = np.log(table.mass_range)
        self.lu_range = np.log(table.friction_range)
        self.v_range = table.speed_range
        # measured mass / friction are held fixed (not fitted) when the log has them
        self.fixed_lm = np.log(pushlog.mass) if use_measured and pushlog.mass is not None else None
        self.fixed_lu = np.log(pushlog.friction) if use_measured and pushlog.friction is not None else None
        self.k_free = int(self.fixed_lm is None) + int(self.fixed_lu is None)

    # -- predictions -------------------------------------------------------------------
    def _f0(self, v, lm, lu) -> np.ndarray:
        v = np.clip(v, *self.v_range)
        m = np.exp(np.clip(lm, *self.lm_range))
        mu = np.exp(np.clip(lu, *self.lu_range))
        return self.table.log_displacement(v, m, mu)

    def predict_push(self, effect: Effect | None, value: float, lm_p, lu_p, idx=None) -> np.ndarray:
        """log d of pushes ``idx`` (all by default) given per-push (log m, log mu)."""
        sel = slice(None) if idx is None else idx
        v, phi = self.v[sel], self.phi[sel]
        if effect is None or value == 0.0:
            return self._f0(v, lm_p, lu_p)
        if effect.kind == MODEL:
            s = effect.per_push(value, phi)
            base = self._f0(v, lm_p, lu_p)
            m = np.exp(np.clip(lm_p, *self.lm_range))
            mu = np.exp(np.clip(lu_p, *self.lu_range))
            return base + self.etables.delta(effect.table_key, v, m, mu, s)
        if effect.kind == SPEED:
            return self._f0(transform_speed(effect, value, v), lm_p, lu_p)
        if effect.kind == FRICTION:
            mu = transform_friction(effect, value, np.exp(lu_p), phi)
            return self._f0(v, lm_p, np.log(np.maximum(mu, 1e-9)))
        raise ValueError(f"unknown effect kind {effect.kind!r}")

    def predict(self, effect: Effect | None, value: float, fit: ObjectFit) -> np.ndarray:
        return self.predict_push(effect, value, fit.lm[self.obj], fit.lu[self.obj])

    def sse(self, pred: np.ndarray) -> np.ndarray:
        return np.bincount(self.obj, (pred - self.y) ** 2, minlength=self.n_obj)

    # -- fits --------------------------------------------------------------------------
    def initial_fit(self) -> ObjectFit:
        """Baseline fit: Scorer's grid search (plus its polish), then refined here."""
        width = int(self.counts.max())
        V = np.full((self.n_obj, width), self.v[0])
        D = np.full((self.n_obj, width), np.nan)
        slot = np.zeros(self.obj.size, dtype=int)
        seen = np.zeros(self.n_obj, dtype=int)
        for p, i in enumerate(self.obj):
            slot[p] = seen[i]
            seen[i] += 1
        V[self.obj, slot] = self.v
        D[self.obj, slot] = self.log.displacement
        f = Scorer(self.table, grid=self.grid).fit(V, D)
        start = ObjectFit(np.log(f.mass), np.log(f.friction), np.full(self.n_obj, np.inf))
        if self.fixed_lm is not None:
            start.lm = self.fixed_lm.copy()
        if self.fixed_lu is not None:
            start.lu = self.fixed_lu.copy()
        if self.k_free == 1:
            # the 2-D grid optimum's free coordinate is no start for a 1-D fit at the
            # measured value: search the free axis on a grid first (global, like Scorer)
            free_m = self.fixed_lm is None
            axis = np.linspace(*(self.lm_range if free_m else self.lu_range), self.grid)
            best = np.full(self.n_obj, np.inf)
            for x in axis:
                lm = np.full(self.n_obj, x) if free_m else start.lm
                lu = start.lu if free_m else np.full(self.n_obj, x)
                sse = self.sse(self.predict_push(None, 0.0, lm[self.obj], lu[self.obj]))
                take = sse < best
                best = np.where(take, sse, best)
                if free_m:
                    start.lm = np.where(take, x, start.lm)
                else:
                    start.lu = np.where(take, x, start.lu)
        return self.refine(None, 0.0, start)

    def refine(self, effect: Effect | None, value: float, start: ObjectFit, iters: int = 8) -> ObjectFit:
        """Levenberg-Marquardt on every object's (log m, log mu) at a fixed effect magnitude."""
        lm, lu = start.lm.copy(), start.lu.copy()
        n, P, obj = self.n_obj, self.obj.size, self.obj
        idx3 = np.concatenate([np.arange(P)] * 3)
        lam = np.full(n, 1e-3)
        for _ in range(iters):
            lmp, lup = lm[obj], lu[obj]
            pred3 = self.predict_push(
                effect,
                value,
                np.concatenate([lmp, lmp + _H, lmp]),
                np.concatenate([lup, lup, lup + _H]),
                idx3,
            )
            pred, jm, ju = (
                pred3[:P],
                (pred3[P : 2 * P] - pred3[:P]) / _H,
                (pred3[2 * P :] - pred3[:P]) / _H,
            )
            r = pred - self.y
            if self.fixed_lm is not None:
                jm = np.zeros_like(jm)
            if self.fixed_lu is not None:
                ju = np.zeros_like(ju)
            sse = np.bincount(obj, r * r, minlength=n)
            a11 = np.bincount(obj, jm * jm, minlength=n)
            a12 = np.bincount(obj, jm * ju, minlength=n)
            a22 = np.bincount(obj, ju * ju, minlength=n)
            b1 = np.bincount(obj, jm * r, minlength=n)
            b2 = np.bincount(obj, ju * r, minlength=n)
            # a fixed parameter has a zero column; a unit diagonal keeps its step at 0
            a11 = np.where(a11 > 0, a11, 1.0)
            a22 = np.where(a22 > 0, a22, 1.0)
            d11, d22 = a11 * (1 + lam) + 1e-12, a22 * (1 + lam) + 1e-12
            det = d11 * d22 - a12 * a12
            det = np.where(np.abs(det) > 1e-300, det, 1e-300)
            sm = -(d22 * b1 - a12 * b2) / det
            su = -(d11 * b2 - a12 * b1) / det
            tm = np.clip(lm + sm, *self.lm_range)
            tu = np.clip(lu + su, *self.lu_range)
            trial = self.sse(self.predict_push(effect, value, tm[obj], tu[obj]))
            better = trial < sse
            lm = np.where(better, tm, lm)
            lu = np.where(better, tu, lu)
            lam = np.where(better, lam * 0.3, lam * 10.0)
        final = self.sse(self.predict_push(effect, value, lm[obj], lu[obj]))
        return ObjectFit(lm, lu, final)

    def profile(self, effect: Effect, values: np.ndarray, start: ObjectFit) -> tuple[np.ndarray, list[ObjectFit]]:
        """Per-object SSE (len(values), N) over a sorted grid of magnitudes containing 0."""
        values = np.asarray(values, float)
        zero = int(np.argmin(np.abs(values)))
        fits: list[ObjectFit | None] = [None] * values.size
        fits[zero] = self.refine(effect, float(values[zero]), start, iters=3)
        for order in (range(zero + 1, values.size), range(zero - 1, -1, -1)):
            prev = fits[zero]
            for j in order:
                fits[j] = self.refine(effect, float(values[j]), prev, iters=5)
                prev = fits[j]
        return np.stack([f.sse for f in fits]), fits  # type: ignore[union-attr]
