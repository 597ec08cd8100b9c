"""What a model predicts for pushes: the push table, the effect tables' terms and the discrepancy, read at the
speeds and frictions the model's effects give the pusher and the box.

:class:`Predicting` is the part of :class:`imply.diagnose.fit.Problem` that makes predictions; it reads the
problem's table (``table``, ``etables``), its conditions (``c_v``, ``c_phi``, ``c_obj``, ``cond``, ``n_cond``),
the table's ranges (``v_range``, ``lm_range``, ``lu_range``) and the observables beside the displacement (``use_t``,
``aux``, ``aux_cols``, ``t_cond``, ``t_kind``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from imply.diagnose.candidates import Model, discrepancy_basis, scaled, terms


def distinct_blocks(n_blocks: int, *columns: np.ndarray) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Columns (n,) made of ``n_blocks`` equal-length blocks: the rows of the first of each set of equal
    blocks, and for every row its position among those rows (None, None where every block differs)."""
    if n_blocks < 2:
        return None, None
    size = columns[0].size // n_blocks
    seen: dict[bytes, int] = {}
    which = np.array(
        [
            seen.setdefault(b"".join(c[b * size : (b + 1) * size].tobytes() for c in columns), len(seen))
            for b in range(n_blocks)
        ]
    )
    if len(seen) == n_blocks:
        return None, None
    firsts = np.unique(which, return_index=True)[1]
    within = np.arange(size)
    return (firsts[:, None] * size + within).ravel(), (which[:, None] * size + within).ravel()


@dataclass(frozen=True)
class ObjectFit:
    """Per-object fit: (N,) log mass, log friction and weighted sum of squares (whitened)."""

    lm: np.ndarray
    lu: np.ndarray
    sse: np.ndarray


@dataclass(frozen=True)
class Prediction:
    """Predicted log d (n,) and the aux observables (n, K) at some conditions, and what of them was
    extrapolated beyond the tables.

    ``extrapolated_d`` / ``extrapolated_t`` are the linear extrapolation parts added (None where no
    condition left the table's range)."""

    log_d: np.ndarray
    log_t: np.ndarray | None
    extrapolated_d: np.ndarray | None
    extrapolated_t: np.ndarray | None

    def extrapolation_sizes(self) -> tuple[np.ndarray, np.ndarray | None]:
        """|log d part| (n,) and |aux part| (n, K) of the extrapolation per condition (zeros where there was none)."""
        size_d = np.abs(self.extrapolated_d) if self.extrapolated_d is not None else np.zeros(self.log_d.size)
        if self.log_t is None:
            return size_d, None
        return size_d, np.abs(self.extrapolated_t) if self.extrapolated_t is not None else np.zeros(self.log_t.shape)


class Predicting:
    """Predictions of a push log's conditions, and of pushes at any conditions (a mixin of
    :class:`imply.diagnose.fit.Problem`)."""

    @cached_property
    def _linear(self):
        from scipy.interpolate import RegularGridInterpolator

        t = self.table
        return RegularGridInterpolator((t.speeds, np.log(t.masses), np.log(t.frictions)), t.log_d, method="linear")

    def interpolation_indicator(self, objs: ObjectFit, model: Model | None = None, theta=None):
        """Per row, |cubic - linear| interpolation of the push table (and of the stop-time table) at
        each push as the model sees it: large where the tables' interpolation is unsure."""
        v = self.c_v
        lu = objs.lu[self.c_obj]
        if model is not None and model.dim:
            t = terms(model, theta, self.c_phi)
            v = v * (1.0 + t.gain) + t.offset
            lu = lu + np.log(np.maximum(t.friction, 1e-6))
        v = np.clip(v, *self.v_range)
        lm = np.clip(objs.lm[self.c_obj], *self.lm_range)
        lu = np.clip(lu, *self.lu_range)
        cubic = self.table.log_displacement(v, np.exp(lm), np.exp(lu))
        ind_d = np.abs(cubic - self._linear(np.stack([v, lm, lu], 1)))[self.cond]
        ind_t = None
        if self.use_t:
            ind = self.etables.aux_interpolation_indicator(v, np.exp(lm), np.exp(lu))[:, self.aux_cols]
            ind_t = ind[self.t_cond, self.t_kind]
        return ind_d, ind_t

    def predict(self, model: Model, theta, lm_c, lu_c, cond=None, blocks: int = 1) -> Prediction:
        """log d and the aux observables at conditions ``cond`` (all by default) given per-condition log m, log mu,
        and theta (p,) or per condition (n, p) (:meth:`predict_at` at the conditions' speeds and directions)."""
        idx = np.arange(self.n_cond) if cond is None else cond
        return self.predict_at(model, theta, self.c_v[idx], self.c_phi[idx], lm_c, lu_c, blocks=blocks)

    def predict_at(
        self, model: Model, theta, speed, phi, lm_c, lu_c, *, load: np.ndarray | None = None, blocks: int = 1
    ) -> Prediction:
        """log d and the aux observables of pushes at logged ``speed`` and direction ``phi`` (n,) of objects of log
        mass and log friction ``lm_c``, ``lu_c`` (n,) carrying ``load`` (n,) kg more (a probe's known added mass;
        None: none), under theta (p,) or per push (n, p). ``blocks``: the rows are that many equal-length settings
        (:meth:`residuals`); the tables are read once for settings that put every push at the same point.

        A speed or friction that the model's effects carry outside the table's range is read at
        the range's edge and extrapolated linearly (the edge's slope); the prediction keeps what
        was extrapolated (:meth:`Prediction.extrapolation_sizes`)."""
        v = np.asarray(speed, float)
        m = np.exp(np.clip(lm_c, *self.lm_range))
        if load is not None:
            m = np.clip(m + load, *np.exp(self.lm_range))
            lm_c = np.log(m)
        lu = np.asarray(lu_c, float)
        t = None
        if model.dim:
            t = terms(model, theta, phi)
            v = v * (1.0 + t.gain) + t.offset
            lu = lu + np.log(np.maximum(t.friction, 1e-6))
        vc, luc = np.clip(v, *self.v_range), np.clip(lu, *self.lu_range)
        mu = np.exp(luc)
        # a step in an effect's level or in the discrepancy moves no push's point: such settings share reads
        rows, back = distinct_blocks(blocks, vc, m, mu)
        vr, mr, mur = (vc, m, mu) if rows is None else (vc[rows], m[rows], mu[rows])

        def spread(values: np.ndarray) -> np.ndarray:
            return values if back is None else values[back]

        pd = spread(self.table.log_displacement(vr, mr, mur))
        pt = spread(self.etables.aux_log(vr, mr, mur)[:, self.aux_cols]) if self.use_t else None
        ext_d = ext_t = None
        out = (vc != v) | (luc != lu)
        if out.any():
            # linear extrapolation from the edge, slopes by one-sided differences inward
            o = np.flatnonzero(out)
            dv, dlu = (v - vc)[o], (lu - luc)[o]
            hv = np.where(vc[o] > 0.5 * sum(self.v_range), -0.01, 0.01)
            hu = np.where(luc[o] > 0.5 * sum(self.lu_range), -0.02, 0.02)
            mo = m[o]
            f0 = self.table.log_displacement(vc[o], mo, mu[o])
            sv = (self.table.log_displacement(vc[o] + hv, mo, mu[o]) - f0) / hv
            su = (self.table.log_displacement(vc[o], mo, np.exp(luc[o] + hu)) - f0) / hu
            ext_d = np.zeros(v.size)
            ext_d[o] = sv * dv + su * dlu
            pd = pd + ext_d
            if self.use_t:
                cols = self.aux_cols
                g0 = self.etables.aux_log(vc[o], mo, mu[o])[:, cols]
                tv = (self.etables.aux_log(vc[o] + hv, mo, mu[o])[:, cols] - g0) / hv[:, None]
                tu = (self.etables.aux_log(vc[o], mo, np.exp(luc[o] + hu))[:, cols] - g0) / hu[:, None]
                ext_t = np.zeros(pt.shape)
                ext_t[o] = tv * dv[:, None] + tu * dlu[:, None]
                pt = pt + ext_t
        if t is not None:
            pts = self.etables.points(vr, mr, mur) if t.tables else None
            for key, s in t.tables:
                vals = spread(self.etables.level_values(key, pts))
                dd, dt = self.etables.mix_levels(key, vals, np.broadcast_to(s, vc.shape))
                pd = pd + dd
                if self.use_t:
                    pt = pt + dt[:, self.aux_cols]
        found = model.discrepancy if model.dim else None
        if found is not None:
            beta = np.asarray(theta, float)[..., found[1]]
            dd, dt = self.discrepancy_terms(found[0], beta, np.asarray(speed, float), lm_c, lu_c)
            pd = pd + dd
            if self.use_t:
                pt = pt + dt
        return Prediction(pd, pt, ext_d, ext_t)

    def discrepancy_terms(self, c, beta: np.ndarray, speed: np.ndarray, lm_c, lu_c) -> tuple[np.ndarray, np.ndarray]:
        """The discrepancy ``c`` at coefficients ``beta`` ((q,) or per push (n, q)) of pushes at logged ``speed``
        (n,): its log d part (n,) and each aux observable's part (n, K, its own coefficients), at the objects'
        (log m, log mu)."""
        sv = scaled(speed, *self.v_range)
        sm = scaled(lm_c, *self.lm_range)
        su = scaled(lu_c, *self.lu_range)
        bd, bt = discrepancy_basis(sv, np.broadcast_to(sm, sv.shape), np.broadcast_to(su, sv.shape))
        beta = np.broadcast_to(beta, (sv.size, c.dim))
        k, kt = bd.shape[1], bt.shape[1]
        dd = np.einsum("nk,nk->n", bd, beta[:, :k])
        n_aux = (c.dim - k) // kt
        dt = np.zeros((sv.size, len(self.aux)))
        for a in range(min(n_aux, len(self.aux))):
            dt[:, a] = np.einsum("nk,nk->n", bt, beta[:, k + a * kt : k + (a + 1) * kt])
        return dd, dt

    def table_terms(self, model: Model, theta, lm_c, lu_c) -> list[tuple[str, np.ndarray, np.ndarray | None]]:
        """Each tabulated term of the model at every condition: (key, Delta log d (C,), Delta aux (C, K))."""
        if not model.dim:
            return []
        v, phi = self.c_v, self.c_phi
        t = terms(model, theta, phi)
        v = np.clip(v * (1.0 + t.gain) + t.offset, *self.v_range)
        m = np.exp(np.clip(lm_c, *self.lm_range))
        mu = np.exp(np.clip(lu_c + np.log(np.maximum(t.friction, 1e-6)), *self.lu_range))
        out = []
        for key, s in t.tables:
            dd, dt = self.etables.delta_both(key, v, m, mu, s)
            out.append((key, dd, dt[:, self.aux_cols] if self.use_t else None))
        return out
