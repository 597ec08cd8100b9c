"""What a model predicts for pushes: the push table, the effect tables' terms and the discrepancy, read at the
speeds and frictions the model's effects give the pusher and the box.

:class:`Predicting` is the part of :class:`imply.diagnose.inference.fit.Problem` that makes predictions; it reads the
problem's table (``table``, ``etables``), its conditions (``c_v``, ``c_phi``, ``c_obj``, ``cond``, ``n_cond``),
the table's ranges (``v_range``, ``lm_range``, ``lu_range``) and the observables beside the displacement (``use_t``,
``aux``, ``aux_cols``, ``aux_col_tuple``, ``t_cond``, ``t_kind``).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from imply.diagnose.physics.candidates import Model, discrepancy_basis, scaled, terms
from imply.diagnose.physics.effect_tables import mix_between


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


def _clip(x, bounds: tuple[float, float]) -> np.ndarray:
    """``np.clip(x, *bounds)`` as two ufuncs (the same values; a prediction clips a few times per call, tens of
    thousands of calls per diagnosis)."""
    return np.minimum(np.maximum(x, bounds[0]), bounds[1])


class Predicting:
    """Predictions of a push log's conditions, and of pushes at any conditions (a mixin of
    :class:`imply.diagnose.inference.fit.Problem`)."""

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
        NaN or None: none), under theta (p,) or per push (n, p). ``blocks``: the rows are that many equal-length
        settings (:meth:`residuals`); the tables are read once for settings that put every push at the same point.

        A speed or friction that the model's effects carry outside the table's range is read at
        the range's edge and extrapolated linearly (the edge's slope); the prediction keeps what
        was extrapolated (:meth:`Prediction.extrapolation_sizes`)."""
        v = np.asarray(speed, float)
        m = np.exp(_clip(lm_c, self.lm_range))
        if load is not None:
            # pushes without an added mass (NaN) keep their mass and log mass as they are
            loaded = ~np.isnan(load)
            heavier = np.clip(m + load, *np.exp(self.lm_range))
            m = np.where(loaded, heavier, m)
            lm_c = np.where(loaded, np.log(heavier), lm_c)
        lu = np.asarray(lu_c, float)
        t = None
        if model.dim:
            t = terms(model, theta, phi)
            # a model without speed or friction terms leaves every push where it is (a gain of 0, a factor of 1)
            if model.moves_speed:
                v = v * (1.0 + t.gain) + t.offset
            if model.moves_friction:
                lu = lu + np.log(np.maximum(t.friction, 1e-6))
        vc, luc = _clip(v, self.v_range), _clip(lu, self.lu_range)
        mu = np.exp(luc)
        # a step in an effect's level or in the discrepancy moves no push's point: such settings share reads
        rows, back = distinct_blocks(blocks, vc, m, mu)
        vr, mr, mur = (vc, m, mu) if rows is None else (vc[rows], m[rows], mu[rows])

        def spread(values: np.ndarray) -> np.ndarray:
            return values if back is None else values[back]

        # every table is read at the same points (v, log m, log mu), each clipped to its own axes
        pts = np.stack([vr, np.log(mr), np.log(mur)], axis=-1)
        pd = spread(self.table.log_displacement_at(pts))
        pt = spread(self.etables.aux_log_at(pts, self.aux_col_tuple)) if self.use_t else None
        ext_d = ext_t = None
        out = (vc != v) | (luc != lu)
        if out.any():
            # linear extrapolation from the edge, slopes by one-sided differences inward
            o = np.flatnonzero(out)
            dv, dlu = (v - vc)[o], (lu - luc)[o]
            hv = np.where(vc[o] > 0.5 * sum(self.v_range), -0.01, 0.01)
            hu = np.where(luc[o] > 0.5 * sum(self.lu_range), -0.02, 0.02)
            mo, muo = m[o], mu[o]
            # the edge is where the tables were just read; a step inward in speed and one in friction are read
            # together
            lm_o, lu_o = np.log(mo), np.log(muo)
            inward = np.concatenate(
                [
                    np.stack([vc[o] + hv, lm_o, lu_o], axis=-1),
                    np.stack([vc[o], lm_o, np.log(np.exp(luc[o] + hu))], axis=-1),
                ]
            )
            f0 = pd[o]
            fv, fu = np.split(self.table.log_displacement_at(inward), 2)
            sv = (fv - f0) / hv
            su = (fu - f0) / hu
            ext_d = np.zeros(v.size)
            ext_d[o] = sv * dv + su * dlu
            pd = pd + ext_d
            if self.use_t:
                g0 = pt[o]
                gv, gu = np.split(self.etables.aux_log_at(inward, self.aux_col_tuple), 2)
                tv = (gv - g0) / hv[:, None]
                tu = (gu - g0) / hu[:, None]
                ext_t = np.zeros(pt.shape)
                ext_t[o] = tv * dv[:, None] + tu * dlu[:, None]
                pt = pt + ext_t
        if t is not None and t.tables:
            # every tabulated term of the model read in one pass, at the levels its points fall between alone (a
            # table holds up to seven; the spline's cost grows with the columns read), then mixed between them
            cols = self.aux_col_tuple if self.use_t else ()
            brackets = [self.etables.brackets(key, np.broadcast_to(s, vc.shape)) for key, s in t.tables]
            lowest = [int(lower.min()) for lower, _ in brackets]
            reads = tuple(
                (key, tuple(range(low, int(lower.max()) + 2)))
                for (key, _), (lower, _), low in zip(t.tables, brackets, lowest, strict=True)
            )
            values = spread(self.etables.read_levels(reads, self.etables.effect_points(pts), cols))
            widths = np.cumsum([(1 + len(cols)) * len(levels) for _, levels in reads])[:-1]
            parts = zip(reads, brackets, lowest, np.split(values, widths, axis=1), strict=True)
            for (_, levels), (lower, weight), low, vals in parts:
                dd, dt = mix_between(vals, lower - low, weight, len(levels))
                pd = pd + dd
                if self.use_t:
                    pt = pt + dt
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
