"""Joint fits of a push log: global effect parameters and every object's (mass, friction).

The prediction for a push of object i at logged speed v in direction phi under a model
(:class:`imply.diagnose.physics.candidates.Model`, parameters theta) is, for each observable,

    log d = f(v', m_i, mu') + sum_k Delta_k(v', m_i, mu'; s_k)
    log a = f_a(v', m_i, mu') + sum_k Delta_a,k(v', m_i, mu'; s_k)     (each observable a the log has)

with v' the pusher's actual speed and mu' the friction the push sees under the model's
speed and friction terms, f the push table, f_a the table of the observable a beside the
displacement (log stop time, log of the pusher's measured mean speed: the "aux" rows) and
Delta the effect tables (:mod:`imply.diagnose.physics.effect_tables`). The aux rows are stacked
observable by observable: row r is push ``t_row[r]``'s observable ``aux[t_kind[r]]``.
Replicate pushes (same object, speed and direction) share one prediction. Residuals are whitened by each observable's noise sd
and weighted (0 for a flagged outlier), so the sum of squares is a chi-square at the
noise.

Fits are Gauss-Newton / Levenberg-Marquardt with finite-difference Jacobians: per-object
(log m, log mu) alone at fixed theta (:meth:`Problem.refine`, vectorised over objects:
2 x 2 normal equations per object), or theta and every object's parameters jointly
(:meth:`Problem.fit`), the objects' blocks eliminated by their Schur complement, bounds
by projection: a parameter at its bound that the data pull past it, an object's or theta's, is held there for
the step. A measured mass or friction is held fixed. At a joint optimum each
object's contribution to the profiled sum of squares is kept as a quadratic in theta
(:class:`JointFit`), which gives leave-objects-out fits in closed form (one Newton step).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cache, cached_property

import numpy as np

from imply.diagnose.inference.launch import FreeLaunch
from imply.diagnose.inputs.observables import Observables
from imply.diagnose.inputs.pushlog import PushLog
from imply.diagnose.physics.candidates import Model
from imply.diagnose.physics.effect_tables import EffectTables
from imply.diagnose.physics.prediction import ObjectFit, Predicting, Prediction
from imply.diagnose.physics.probe_fit import ProbeRows
from imply.diagnose.tails import chi2_ppf
from imply.table import PushTable

# ObjectFit and Prediction live with the predictions (imply.diagnose.physics.prediction); the fits hand them out
__all__ = ["JointFit", "ObjectFit", "Prediction", "Problem"]

_H = 1e-4  # finite-difference step in log m and log mu


@dataclass(frozen=True)
class JointFit:
    """A model's joint fit: parameters, objects, and each object's quadratic in theta."""

    model: Model
    theta: np.ndarray
    objects: ObjectFit
    S: np.ndarray  # (N, p, p) each object's Schur-complemented Gauss-Newton Hessian (half)
    b: np.ndarray  # (N, p) each object's profiled gradient (half)
    iterations: int = 0

    @property
    def sse(self) -> float:
        """The data's whitened sum of squares (the prior's term is not in it)."""
        return float(self.objects.sse.sum())

    @property
    def prior(self) -> np.ndarray:
        """(p,) the prior precision of each component (the discrepancy's; 0 for the effects)."""
        return self.model.prior_precision()

    def pulled_past_bounds(self, level: float = 0.95) -> dict[str, float]:
        """Library effects at their bound that the pushes pull beyond it: {name: the one-step profiled drop of the
        sum of squares beyond the bound}, where that drop is above the chi-square quantile at ``level`` (1 df)."""
        crit = chi2_ppf(level, 1)
        b, S = self.b.sum(0), self.S.sum(0)
        out = {}
        for c, sl in zip(self.model.candidates, self.model.slices(), strict=True):
            e = c.bound_direction(self.theta[sl])
            if e is None:
                continue
            g, h = float(e @ b[sl]), float(e @ S[sl, sl] @ e)
            # the sum of squares falls along -g: outward when -g points along e
            if h > 0 and -g > 0 and g * g / h > crit:
                out[c.name] = g * g / h
        return out

    def covariance(self) -> np.ndarray:
        """Covariance of theta (whitened residuals: unit noise), from the summed Hessian and the prior."""
        p = self.theta.size
        if p == 0:
            return np.zeros((0, 0))
        H = self.S.sum(0) + np.diag(self.prior)
        return np.linalg.pinv(H + 1e-12 * np.eye(p))

    def leave_out(self, folds: np.ndarray) -> dict[int, np.ndarray]:
        """theta fitted without each fold's objects, by one Newton step from the joint optimum."""
        out = {}
        p = self.theta.size
        P = np.diag(self.prior) if p else np.zeros((0, 0))
        H = self.S.sum(0) + P
        for f in np.unique(folds):
            keep = folds != f
            Hk = self.S[keep].sum(0) + P
            # the fold's own pull, taken away (at a bound the full gradient is held by the bound)
            gf = self.b[~keep].sum(0)
            step = np.linalg.lstsq(Hk + 1e-9 * np.trace(H) / max(p, 1) * np.eye(p), gf, rcond=None)[0]
            out[int(f)] = self.model.project(self.theta + step) if p else self.theta
        return out

    def heldout_sse_quadratic(self, folds: np.ndarray) -> np.ndarray:
        """Each object's sum of squares at the theta fitted without its fold (quadratic model)."""
        if self.theta.size == 0:
            return self.objects.sse.copy()
        out = np.empty_like(self.objects.sse)
        for f, th in self.leave_out(folds).items():
            d = th - self.theta
            sel = folds == f
            out[sel] = self.objects.sse[sel] + 2 * self.b[sel] @ d + np.einsum("p,npq,q->n", d, self.S[sel], d)
        return np.maximum(out, 0.0)


def _baseline_sds(pushlog: PushLog, aux: tuple[str, ...]) -> dict[str, np.ndarray | None]:
    """The per-row sds of a reference baseline taken out of ``pushlog`` (:attr:`PushLog.baseline_sd`), as
    :class:`Problem`'s fields: log d's (n,) and the aux rows' (n K,), zeros for an observable without one."""
    sds = pushlog.baseline_sd
    if not sds:
        return {}
    zeros = np.zeros(pushlog.n)
    return {
        "baseline_sd_d": np.asarray(sds.get("displacement", zeros), float),
        "baseline_sd_t": np.concatenate([np.asarray(sds.get(a, zeros), float) for a in aux]) if aux else None,
    }


@dataclass(frozen=True, eq=False)
class Problem(Predicting, FreeLaunch):
    """A push log against a baseline table, its effect tables, its noise, weights and model error.

    Immutable: :meth:`with_noise`, :meth:`with_weights` and :meth:`with_model_error` return a new
    problem, so each step of the diagnosis says what it fits under. Build one with :meth:`of`.
    """

    log: PushLog
    table: PushTable
    etables: EffectTables | None
    grid: int
    obj: np.ndarray  # (n,) object index per push
    n_obj: int
    v: np.ndarray
    phi: np.ndarray
    y: np.ndarray  # log displacement per push
    cond: np.ndarray  # (n,) condition index per push: replicate pushes share one prediction
    n_cond: int
    c_obj: np.ndarray
    c_v: np.ndarray
    c_phi: np.ndarray
    counts: np.ndarray  # pushes per object
    lm_range: np.ndarray
    lu_range: np.ndarray
    v_range: tuple[float, float]
    fixed_lm: np.ndarray | None  # measured log mass, held fixed
    fixed_lu: np.ndarray | None  # measured log friction, held fixed
    use_t: bool  # the log has observables beside the displacement that the fits use
    y_t: np.ndarray | None  # (n K,) their logs, stacked observable by observable (None without)
    aux: tuple[str, ...] = ()  # the K observables (names of imply.diagnose.physics.effect_tables.AUX)
    noise_d: float = 1.0
    noise_t: np.ndarray | float = 1.0  # (K,) or one sd for all
    model_err_d: np.ndarray | None = None  # per row (None: zeros)
    model_err_t: np.ndarray | None = None  # per aux row
    # the sd of the reference baseline taken out of each row (imply.diagnose.reference; zeros: none)
    baseline_sd_d: np.ndarray | None = None  # per row
    baseline_sd_t: np.ndarray | None = None  # per aux row
    w_d: np.ndarray | None = None  # per row, 0 for a flagged outlier (None: ones)
    w_t: np.ndarray | None = None  # per aux row (None: ones where aux observables are used)
    observables: Observables = Observables()  # what the fit was asked to read
    probes: ProbeRows | None = None  # the log's calibration probes as fit rows, where it has them and they are used
    # (C, 1 + K) each condition's prediction (log d, then the aux observables) per unit log speed: the direction its
    # launch is free to move it (None: the launch is the table's); see with_free_launch
    launch: np.ndarray | None = None

    def __post_init__(self) -> None:
        # defaults that depend on the log's length
        n = self.y.size
        if self.model_err_d is None:
            object.__setattr__(self, "model_err_d", np.zeros(n))
        if self.model_err_t is None:
            object.__setattr__(self, "model_err_t", np.zeros(n * len(self.aux)))
        if self.baseline_sd_d is None:
            object.__setattr__(self, "baseline_sd_d", np.zeros(n))
        if self.baseline_sd_t is None:
            object.__setattr__(self, "baseline_sd_t", np.zeros(n * len(self.aux)))
        if self.w_d is None:
            object.__setattr__(self, "w_d", np.ones(n))
        if self.w_t is None and self.use_t:
            object.__setattr__(self, "w_t", np.ones(n * len(self.aux)))

    @cached_property
    def t_row(self) -> np.ndarray:
        """(n K,) the push of each aux row."""
        return np.tile(np.arange(self.y.size), len(self.aux))

    @cached_property
    def t_kind(self) -> np.ndarray:
        """(n K,) the observable (index into :attr:`aux`) of each aux row."""
        return np.repeat(np.arange(len(self.aux)), self.y.size)

    @cached_property
    def t_cond(self) -> np.ndarray:
        """(n K,) the condition of each aux row's push."""
        return self.cond[self.t_row]

    @cached_property
    def aux_cols(self) -> np.ndarray:
        """(K,) where each observable of :attr:`aux` sits in the effect tables' observables."""
        return np.array([self.etables.aux_index(a) for a in self.aux], int) if self.aux else np.zeros(0, int)

    @cached_property
    def aux_col_tuple(self) -> tuple[int, ...]:
        """:attr:`aux_cols` as a tuple: the key under which the tables keep their splines of these columns alone."""
        return tuple(int(a) for a in self.aux_cols)

    def aux_rows(self, name: str) -> np.ndarray:
        """Indices of the aux rows of observable ``name`` (empty if unused)."""
        return np.flatnonzero(self.t_kind == self.aux.index(name)) if name in self.aux else np.zeros(0, int)

    @classmethod
    def of(
        cls,
        pushlog: PushLog,
        table: PushTable,
        etables: EffectTables | None,
        *,
        grid: int = 101,
        observables: Observables | None = None,
    ) -> Problem:
        """The problem of a push log at unit noise, no model error and every push weighted 1; the observables
        beside the displacement are those the log has, the tables hold and ``observables`` asks for (None: the
        defaults, the diagnosis options' own), and the log's probes enter where it has them and it asks for them."""
        observables = observables or Observables()
        obj = pushlog.obj
        v = pushlog.speed
        phi = pushlog.direction
        # replicate pushes share one prediction: unique (object, speed, direction)
        key = np.stack([obj.astype(float), np.round(v, 9), np.round(np.mod(phi, 2 * np.pi), 6)], 1)
        uniq, first, cond = np.unique(key, axis=0, return_index=True, return_inverse=True)
        n_obj = len(pushlog.objects)
        held = etables.aux if etables is not None else ()
        aux = tuple(a for a in held if observables.wants(a) and pushlog.aux(a) is not None)
        use_t = bool(aux)
        use_measured = observables.measured
        probes = None
        if observables.probes and pushlog.probes is not None:
            probes = ProbeRows.of(pushlog.probes, aux=aux, scene=table.meta.get("scene"))
        return cls(
            log=pushlog,
            table=table,
            etables=etables,
            grid=grid,
            obj=obj,
            n_obj=n_obj,
            v=v,
            phi=phi,
            y=pushlog.log_d,
            cond=cond.ravel(),
            n_cond=uniq.shape[0],
            c_obj=obj[first],
            c_v=v[first],
            c_phi=phi[first],
            counts=np.bincount(obj, minlength=n_obj).astype(float),
            lm_range=np.log(table.mass_range),
            lu_range=np.log(table.friction_range),
            v_range=table.speed_range,
            fixed_lm=np.log(pushlog.mass) if use_measured and pushlog.mass is not None else None,
            fixed_lu=np.log(pushlog.friction) if use_measured and pushlog.friction is not None else None,
            use_t=use_t,
            y_t=np.concatenate([pushlog.aux(a) for a in aux]) if use_t else None,
            aux=aux,
            observables=observables,
            probes=probes,
            **_baseline_sds(pushlog, aux),
        )

    # -- noise, weights and model error: each a new problem ---------------------------
    def with_noise(self, sd_d: float, sd_t) -> Problem:
        """Each observable's noise sd: log d's, and the aux observables' ((K,), or one for all; None: log d's)
        (the model's own error is added by :meth:`with_model_error`)."""
        if not self.use_t:
            return replace(self, noise_d=float(sd_d))
        t = np.broadcast_to(np.asarray(sd_d if sd_t is None else sd_t, float), (len(self.aux),)).copy()
        return replace(self, noise_d=float(sd_d), noise_t=t)

    def with_model_error(self, err_d: np.ndarray, err_t: np.ndarray | None) -> Problem:
        """The model's own error per row (RMS, log units), counted as variance beside the noise."""
        keep_t = not (self.use_t and err_t is not None)
        return replace(
            self,
            model_err_d=np.asarray(err_d, float),
            model_err_t=self.model_err_t if keep_t else np.asarray(err_t, float),
        )

    def with_weights(self, w_d: np.ndarray, w_t: np.ndarray | None) -> Problem:
        """Per-row weights (0 leaves a flagged outlier out of every fit)."""
        if not self.use_t:
            return replace(self, w_d=np.asarray(w_d, float))
        return replace(
            self,
            w_d=np.asarray(w_d, float),
            w_t=np.asarray(w_t if w_t is not None else np.ones(self.t_row.size), float),
        )

    @cached_property
    def k_free(self) -> int:
        """Per-object parameters fitted (mass and friction, less the measured ones)."""
        return int(self.fixed_lm is None) + int(self.fixed_lu is None)

    @cached_property
    def sd_d(self) -> np.ndarray:
        """Per row: noise, model error and the reference baseline's own noise together (log d)."""
        return np.sqrt(self.noise_d**2 + self.model_err_d**2 + self.baseline_sd_d**2)

    @cached_property
    def noise_aux(self) -> np.ndarray:
        """(K,) each observable beside the displacement's noise sd."""
        return np.broadcast_to(np.asarray(self.noise_t, float), (len(self.aux),))

    @cached_property
    def noise_t_rows(self) -> np.ndarray:
        """(n K,) each aux row's noise sd."""
        return self.noise_aux[self.t_kind]

    @cached_property
    def sd_t(self) -> np.ndarray:
        """Per aux row: noise, model error and the reference baseline's own noise together."""
        return np.sqrt(self.noise_t_rows**2 + self.model_err_t**2 + self.baseline_sd_t**2)

    @property
    def n_rows(self) -> int:
        """Pushes (rows) that count in the fit (not flagged)."""
        return int((self.w_d > 0).sum())

    # -- residuals ----------------------------------------------------------------------
    def row_residuals(self, pred: Prediction) -> tuple[np.ndarray, np.ndarray | None]:
        """Raw (unwhitened, unweighted) residuals, observed minus predicted: per push (log d) and per aux row; with
        the launch freed, what is left once each condition's launch is profiled out (on the rows that count)."""
        rd = self.y - pred.log_d[self.cond]
        rt = self.y_t - pred.log_t[self.t_cond, self.t_kind] if self.use_t else None
        if self.launch is None:
            return rd, rt
        n = self.y.size
        sd = self.row_sd[: n + (self.t_row.size if self.use_t else 0)]
        raw = np.concatenate([rd, rt]) if self.use_t else rd
        freed = self._free_launch(raw[None, :] / sd, weighted=False)[0] * sd
        return (freed[:n], freed[n:]) if self.use_t else (freed, None)

    @cached_property
    def _row_objects(self) -> np.ndarray:
        parts = [self.obj]
        if self.use_t:
            parts.append(self.obj[self.t_row])
        if self.probes is not None:
            parts.append(self.probes.row_obj)
        return np.concatenate(parts) if len(parts) > 1 else self.obj

    def _row_obj(self) -> np.ndarray:
        """(rows,) the object of each residual row: pushes, their aux rows, then the probes' rows (every fit
        iteration asks: assembled once)."""
        return self._row_objects

    def object_sse(self, r: np.ndarray) -> np.ndarray:
        return np.bincount(self._row_obj(), r * r, minlength=self.n_obj)

    def residuals(self, model: Model, thetas: np.ndarray, lms: np.ndarray, lus: np.ndarray) -> np.ndarray:
        """Whitened residuals (K, rows) of K settings at once: thetas (K, p), lms and lus (K, N)."""
        lms, lus = np.atleast_2d(lms), np.atleast_2d(lus)
        k = lms.shape[0]
        C = self.n_cond
        speed, phi, obj, load = self._predicted_pushes
        n = speed.size
        th = np.repeat(np.atleast_2d(thetas), n, axis=0) if model.dim else np.zeros(0)
        pred = self.predict_at(
            model,
            th,
            np.tile(speed, k),
            np.tile(phi, k),
            lms[:, obj].ravel(),
            lus[:, obj].ravel(),
            load=None if load is None else np.tile(load, k),
            blocks=k,
        )
        pd = pred.log_d.reshape(k, n)
        pt = None if pred.log_t is None else pred.log_t.reshape(k, n, len(self.aux))
        added = (pd[:, C:], None if pt is None else pt[:, C:]) if n > C else None
        return self._whitened(model, thetas, lms, lus, pd[:, :C], None if pt is None else pt[:, :C], added=added)

    @cached_property
    def _predicted_pushes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None]:
        """What :meth:`residuals` predicts in each setting, in one pass: every condition, then the probes' pushes with
        an added mass. Their speeds, directions and objects (C + a,) and the mass each carries more (NaN for a
        condition; None without such pushes)."""
        pr = self.probes
        if pr is None or not pr.n_added:
            return self.c_v, self.c_phi, self.c_obj, None
        return (
            np.concatenate([self.c_v, pr.added_speed]),
            np.concatenate([self.c_phi, pr.added_phi]),
            np.concatenate([self.c_obj, pr.added_obj]),
            np.concatenate([np.full(self.n_cond, np.nan), pr.added_mass]),
        )

    def _whitened(
        self,
        model: Model,
        thetas: np.ndarray,
        lms: np.ndarray,
        lus: np.ndarray,
        pd: np.ndarray,
        pt: np.ndarray | None,
        *,
        added: tuple[np.ndarray, np.ndarray | None] | None = None,
    ) -> np.ndarray:
        """Whitened residuals (K, rows) of K settings (thetas (K, p), lms and lus (K, N)) from every condition's
        predictions under them: log d ``pd`` (K, C) and the aux observables ``pt`` (K, C, len(aux)); the probes'
        loaded pushes' predictions ``added`` (log d (K, a), the aux observables (K, a, len(aux))) where the caller
        has them, else predicted here."""
        rd = self.w_d * (pd[:, self.cond] - self.y) / self.sd_d
        parts = [rd]
        if self.use_t:
            parts.append(self.w_t * (pt[:, self.t_cond, self.t_kind] - self.y_t) / self.sd_t)
        if self.launch is not None:
            parts = [self._free_launch(np.concatenate(parts, axis=1))]
        if self.probes is not None:
            parts.append(self.probe_residuals(model, np.atleast_2d(thetas), lms, lus, added=added))
        return np.concatenate(parts, axis=1) if len(parts) > 1 else parts[0]

    def aux_noise(self, name: str) -> float | None:
        """The noise sd of observable ``name`` beside the displacement (None where the fit does not use it)."""
        if name not in self.aux:
            return None
        return float(self.noise_aux[self.aux.index(name)])

    @cached_property
    def probe_sd(self) -> np.ndarray:
        """(q,) each probe row's sd, in the order of the probes' ``row_obj``: a friction reading's stated one, the
        loaded pushes' observables' noise, the free strokes' (:meth:`ProbeRows.stroke_noise`)."""
        pr = self.probes
        parts = [pr.friction_sd, np.full(pr.n_added, self.noise_d)]
        parts += [np.full(rows.size, self.aux_noise(name)) for name, rows in pr.aux_rows()]
        parts.append(np.full(pr.stroke_speed.size, pr.stroke_noise(self.aux_noise("pusher_speed"))))
        return np.concatenate(parts)

    @cached_property
    def row_sd(self) -> np.ndarray:
        """(rows,) the sd that whitens each residual row of :meth:`residuals`: pushes, aux rows, probe rows."""
        parts = [np.broadcast_to(self.sd_d, (self.y.size,))]
        if self.use_t:
            parts.append(np.broadcast_to(self.sd_t, (self.t_row.size,)))
        if self.probes is not None:
            parts.append(self.probe_sd)
        return np.concatenate(parts)

    def probe_residuals(
        self,
        model: Model,
        thetas: np.ndarray,
        lms: np.ndarray,
        lus: np.ndarray,
        *,
        added: tuple[np.ndarray, np.ndarray | None] | None = None,
    ) -> np.ndarray:
        """Whitened residuals (K, q) of the log's probes (:class:`imply.diagnose.physics.probe_fit.ProbeRows`, in the order
        of its ``row_obj``) at K settings: thetas (K, p), lms and lus (K, N); ``added``: the loaded pushes'
        predictions, log d (K, a) and the aux observables (K, a, len(aux)), where the caller has them."""
        pr = self.probes
        k = lms.shape[0]
        parts = [pr.friction_prediction(model, thetas if model.dim else np.zeros((k, 0)), lms, lus) - pr.log_friction]
        if pr.n_added:
            a = pr.n_added
            if added is None:
                th = np.repeat(thetas, a, axis=0) if model.dim else np.zeros(0)
                pred = self.predict_at(
                    model,
                    th,
                    np.tile(pr.added_speed, k),
                    np.tile(pr.added_phi, k),
                    lms[:, pr.added_obj].ravel(),
                    lus[:, pr.added_obj].ravel(),
                    load=np.tile(pr.added_mass, k),
                    blocks=k,
                )
                added = (
                    pred.log_d.reshape(k, a),
                    None if pred.log_t is None else pred.log_t.reshape(k, a, len(self.aux)),
                )
            parts.append(added[0] - pr.added_log_d)
            for name, rows in pr.aux_rows():
                got = added[1][:, rows, self.aux.index(name)]
                parts.append(got - pr.added_aux[name][rows])
        if pr.stroke_speed.size:
            pred = pr.free_stroke_prediction(model, thetas if model.dim else np.zeros((k, 0)))
            parts.append(pred - pr.log_stroke)
        return np.concatenate(parts, axis=1) / self.probe_sd

    def _eval_many(self, model: Model, thetas: list, lms: list, lus: list) -> list[np.ndarray]:
        th = np.stack([np.asarray(t, float) for t in thetas]) if model.dim else np.zeros((len(thetas), 0))
        r = self.residuals(model, th, np.stack(lms), np.stack(lus))
        return list(r)

    def stacked_sse(self, r: np.ndarray) -> np.ndarray:
        """Per-object sums of squares (K, N) of stacked residuals (K, rows)."""
        k = r.shape[0]
        ro = self._row_obj()
        idx = (np.arange(k)[:, None] * self.n_obj + ro[None, :]).ravel()
        return np.bincount(idx, (r * r).ravel(), minlength=k * self.n_obj).reshape(k, self.n_obj)

    # -- fits --------------------------------------------------------------------------
    def initial_fit(self, model: Model | None = None, theta=None, n_grid: int | None = None) -> ObjectFit:
        """Every object's (log m, log mu): a global grid search over the table's range (measured values held)
        on the weighted sum of squares of all observables, then refined."""
        model = model or Model()
        theta = np.zeros(0) if theta is None else np.asarray(theta, float)
        n = min(self.grid if n_grid is None else n_grid, 61)
        lm_axis = np.linspace(*self.lm_range, n) if self.fixed_lm is None else None
        lu_axis = np.linspace(*self.lu_range, n) if self.fixed_lu is None else None
        best = np.full(self.n_obj, np.inf)
        lm = self.fixed_lm.copy() if self.fixed_lm is not None else np.zeros(self.n_obj)
        lu = self.fixed_lu.copy() if self.fixed_lu is not None else np.zeros(self.n_obj)
        rows = lm_axis if lm_axis is not None else [None]
        k = lu_axis.size if lu_axis is not None else 1
        # (rows k, N): the search's settings, row by row of log m, each at every log mu
        L = np.repeat(np.stack([lm if a is None else np.full(self.n_obj, a) for a in rows]), k, 0)
        U = np.tile(np.repeat(lu_axis[:, None], self.n_obj, 1) if lu_axis is not None else lu[None, :], (len(rows), 1))
        sse_all = self._grid_sse(model, theta, L, U).reshape(len(rows), k, self.n_obj)
        for a, sse in zip(rows, sse_all, strict=True):
            j = np.argmin(sse, axis=0)
            val = sse[j, np.arange(self.n_obj)]
            take = val < best
            best = np.where(take, val, best)
            if a is not None:
                lm = np.where(take, a, lm)
            if lu_axis is not None:
                lu = np.where(take, lu_axis[j], lu)
        return self.refine(model, theta, ObjectFit(lm, lu, best), iters=15)

    @cached_property
    def _grid_conditions(self) -> tuple[np.ndarray, np.ndarray]:
        """The conditions a grid search without effects tells apart, where every object sits at the same free
        (log m, log mu): (R,) the first condition of each kind and (C,) each condition's kind. Two conditions are
        one kind when their speeds and their objects' measured values agree."""
        lm = self.fixed_lm[self.c_obj] if self.fixed_lm is not None else np.zeros(self.n_cond)
        lu = self.fixed_lu[self.c_obj] if self.fixed_lu is not None else np.zeros(self.n_cond)
        key = np.stack([self.c_v, lm, lu], 1)
        _, first, kind = np.unique(key, axis=0, return_index=True, return_inverse=True)
        return first, kind.ravel()

    def _grid_sse(self, model: Model, theta: np.ndarray, L: np.ndarray, U: np.ndarray) -> np.ndarray:
        """Per-object sums of squares (K, N) at K settings of a grid search (lms ``L`` and lus ``U`` (K, N), theta
        fixed). Objects at the same (log m, log mu) in a setting predict the same for pushes at the same speed (a
        model without effects ignores direction), so each kind of condition is predicted once per setting: the same
        values as :meth:`residuals`' in a fraction of the reads. Settings go in chunks that bound the memory."""
        K, C = L.shape[0], self.n_cond
        if model.dim:
            first, kind = np.arange(C), np.arange(C)
        else:
            first, kind = self._grid_conditions
        R = first.size
        chunk = max(1, 2_000_000 // max(self._row_obj().size + C, 1))
        out = []
        for start in range(0, K, chunk):
            lms, lus = L[start : start + chunk], U[start : start + chunk]
            k = lms.shape[0]
            thetas = np.repeat(theta[None, :], k, 0) if model.dim else np.zeros((k, 0))
            th = np.repeat(thetas, R, axis=0) if model.dim else np.zeros(0)
            pred = self.predict(
                model, th, lms[:, self.c_obj[first]].ravel(), lus[:, self.c_obj[first]].ravel(), np.tile(first, k)
            )
            pd = pred.log_d.reshape(k, R)[:, kind]
            pt = None if pred.log_t is None else pred.log_t.reshape(k, R, len(self.aux))[:, kind]
            out.append(self.stacked_sse(self._whitened(model, thetas, lms, lus, pd, pt)))
        return np.concatenate(out)

    def _free_columns(self, jm: np.ndarray, ju: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.fixed_lm is not None:
            jm = np.zeros_like(jm)
        if self.fixed_lu is not None:
            ju = np.zeros_like(ju)
        return jm, ju

    def refine(
        self, model: Model, theta, start: ObjectFit, iters: int = 8, stencil: np.ndarray | None = None
    ) -> ObjectFit:
        """Levenberg-Marquardt on every object's (log m, log mu) at fixed theta (``stencil``: see
        :meth:`refine_many`)."""
        out = self.refine_many(
            model,
            np.atleast_2d(np.asarray(theta, float)) if model.dim else np.zeros((1, 0)),
            start.lm[None, :],
            start.lu[None, :],
            iters=iters,
            stencil=stencil,
        )
        return ObjectFit(out[0][0], out[1][0], out[2][0])

    def refine_many(
        self,
        model: Model,
        thetas: np.ndarray,
        lm: np.ndarray,
        lu: np.ndarray,
        iters: int = 8,
        stencil: np.ndarray | None = None,
    ):
        """Per-object fits at K parameter settings at once: thetas (K, p), starts (K, N) or (1, N); ``stencil``: the
        residuals (3 K, rows) at the starts, at every log m + H and at every log mu + H, where the caller has them.

        Returns (lm, lu, sse), each (K, N)."""
        K = thetas.shape[0]
        lm = np.broadcast_to(lm, (K, self.n_obj)).copy()
        lu = np.broadcast_to(lu, (K, self.n_obj)).copy()
        if iters <= 0:
            return lm, lu, self.stacked_sse(self.residuals(model, thetas, lm, lu))
        n = K * self.n_obj
        ro = self._row_obj()
        idx = (np.arange(K)[:, None] * self.n_obj + ro[None, :]).ravel()
        lam = np.full((K, self.n_obj), 1e-3)
        th3 = np.concatenate([thetas, thetas, thetas])

        def binc(x):
            return np.bincount(idx, x.ravel(), minlength=n).reshape(K, self.n_obj)

        def stencil_at(lm: np.ndarray, lu: np.ndarray) -> np.ndarray:
            """(3 K, rows): the residuals at (lm, lu), at lm + H and at lu + H."""
            return self.residuals(model, th3, np.concatenate([lm, lm + _H, lm]), np.concatenate([lu, lu, lu + _H]))

        r3 = stencil_at(lm, lu) if stencil is None else stencil
        for it in range(iters):
            r, rm, ru = r3[:K], r3[K : 2 * K], r3[2 * K :]
            jm, ju = self._free_columns((rm - r) / _H, (ru - r) / _H)
            sse = binc(r * r)
            a11, a12, a22 = binc(jm * jm), binc(jm * ju), binc(ju * ju)
            b1, b2 = binc(jm * r), binc(ju * r)
            a11 = np.where(a11 > 0, a11, 1.0)
            a22 = np.where(a22 > 0, a22, 1.0)
            d11, d22 = a11 * (1 + lam) + 1e-12, a22 * (1 + lam) + 1e-12
            det = d11 * d22 - a12 * a12
            det = np.where(np.abs(det) > 1e-300, det, 1e-300)
            tm = np.clip(lm - (d22 * b1 - a12 * b2) / det, *self.lm_range)
            tu = np.clip(lu - (d11 * b2 - a12 * b1) / det, *self.lu_range)
            # the trial's own stencil comes with it, ready for the next step: each object's rows depend on its own
            # (log m, log mu) alone, so the next step's residuals are, object by object, the trial's or the last
            last = it == iters - 1
            t3 = self.residuals(model, thetas, tm, tu) if last else stencil_at(tm, tu)
            trial = self.stacked_sse(t3[:K])
            better = trial < sse
            converged = np.all(np.where(better, sse - trial, 0.0) < 1e-10 * (1 + sse))
            lm = np.where(better, tm, lm)
            lu = np.where(better, tu, lu)
            lam = np.where(better, lam * 0.3, lam * 10.0)
            sse = np.where(better, trial, sse)
            if last or converged:
                break
            r3 = np.where(np.tile(better[:, ro], (3, 1)), t3, r3)
        return lm, lu, sse

    def fit(self, model: Model, theta0, start: ObjectFit, iters: int = 25, tol: float = 1e-8) -> JointFit:
        """theta and every object's (log m, log mu) jointly (Levenberg-Marquardt, Schur complement)."""
        p = model.dim
        theta = model.project(np.asarray(theta0, float)) if p else np.zeros(0)
        objs = self.refine(model, theta, start, iters=4 if p else 10)
        lo, hi = model.lo(), model.hi()
        hstep = 1e-3 * np.maximum(model.scale(), 1e-12)
        lam = 1e-3
        it = 0
        fm, fu = float(self.fixed_lm is None), float(self.fixed_lu is None)
        prec = model.prior_precision()
        rs, signs = self._stencil(model, theta, objs.lm, objs.lu, hstep)
        blocks = self._normal(rs, signs)
        for step_no in range(1, iters + 1):
            it = step_no
            if p == 0:
                break
            A, B, C, g_u, g_t, r0 = blocks
            sse = float(r0 @ r0) + float(prec @ theta**2)
            # an object parameter at its bound that the data pull past it is held there: clipping its step instead
            # would leave theta's step profiled over a move the object cannot make, and the fit would crawl
            A, B, g_u = self._hold_at_bounds(objs, A, B, g_u)
            Ad = A + lam * A * np.eye(2)[None]  # damped object blocks
            Ainv = np.linalg.inv(Ad + 1e-12 * np.eye(2))
            # the prior's half Hessian and half gradient join the objects' profiled ones
            S = (C - np.einsum("naj,nab,nbk->njk", B, Ainv, B)).sum(0) + np.diag(prec)
            rhs = (g_t - np.einsum("naj,nab,nb->nj", B, Ainv, g_u)).sum(0) + prec * theta
            # bounds: components at a bound whose step would leave the box are held
            free = np.ones(p, bool)
            step = np.zeros(p)
            for _ in range(p + 1):
                Sd = S[np.ix_(free, free)] + lam * np.diag(np.diag(S)[free] + 1e-12)
                step = np.zeros(p)
                step[free] = -np.linalg.solve(Sd, rhs[free])
                leaving = free & (((theta <= lo + 1e-12) & (step < 0)) | ((theta >= hi - 1e-12) & (step > 0)))
                if not leaving.any():
                    break
                free &= ~leaving
            new_theta = model.project(theta + step)
            du = -np.einsum("nij,nj->ni", Ainv, g_u + np.einsum("nij,j->ni", B, new_theta - theta))
            lm_new = np.clip(objs.lm + du[:, 0] * fm, *self.lm_range)
            lu_new = np.clip(objs.lu + du[:, 1] * fu, *self.lu_range)
            # the trial is read with its whole stencil, in one pass: taken, its normal equations are ready
            rs_new, signs_new = self._stencil(model, new_theta, lm_new, lu_new, hstep)
            trial = self.stacked_sse(rs_new[:1])[0]
            objective = trial.sum() + float(prec @ new_theta**2)
            if objective < sse:
                gain = sse - objective
                theta, objs = new_theta, ObjectFit(lm_new, lu_new, trial)
                rs, signs = rs_new, signs_new
                lam = max(lam * 0.2, 1e-9)
                if gain < tol * (1.0 + sse):
                    break
                blocks = self._normal(rs, signs)
            else:
                lam *= 10.0
                if lam > 1e8:
                    break
        # the stencil at (theta, objects) starts the last refinement: its first three settings are the refinement's
        objs = self.refine(model, theta, objs, iters=3, stencil=rs[:3])
        A, B, C, g_u, g_t, _ = self._normal(*self._stencil(model, theta, objs.lm, objs.lu, hstep))
        Ainv = np.linalg.inv(A + 1e-12 * np.eye(2))
        S_i = C - np.einsum("naj,nab,nbk->njk", B, Ainv, B)
        b_i = g_t - np.einsum("naj,nab,nb->nj", B, Ainv, g_u)
        return JointFit(model, theta, objs, S_i, b_i, it)

    def _hold_at_bounds(self, objs: ObjectFit, A: np.ndarray, B: np.ndarray, g_u: np.ndarray):
        """The object blocks with every object parameter held that sits at its bound and that the sum of squares
        pulls past it: its row and column of A made the identity's, its row of B and its gradient zero, so that the
        step leaves it where it is and theta's step is profiled over the objects' free parameters alone."""
        eps = 1e-9
        at = np.stack([objs.lm, objs.lu], 1)
        lo = np.array([self.lm_range[0], self.lu_range[0]])
        hi = np.array([self.lm_range[1], self.lu_range[1]])
        held = ((at <= lo + eps) & (g_u > 0)) | ((at >= hi - eps) & (g_u < 0))
        if not held.any():
            return A, B, g_u
        A = np.where(held[:, :, None] | held[:, None, :], 0.0, A)
        for a in range(2):
            A[:, a, a] = np.where(held[:, a], 1.0, A[:, a, a])
        return A, np.where(held[:, :, None], 0.0, B), np.where(held, 0.0, g_u)

    def _stencil(
        self, model: Model, theta: np.ndarray, lm: np.ndarray, lu: np.ndarray, hstep: np.ndarray
    ) -> tuple[np.ndarray, list[float]]:
        """The residuals (3 + p, rows) that the normal equations at (theta, objects' ``lm``, ``lu`` (N,)) difference:
        at the point, at every log m + H, at every log mu + H, and at each component of theta stepped by ``hstep``
        (forward, or backward where forward leaves the admissible set); and each theta step's signed size (p,)."""
        p = model.dim
        thetas = [theta, theta, theta]
        signs = []
        for c, sl in zip(model.candidates, model.slices(), strict=True):
            for j in range(sl.start, sl.stop):
                # a step along component j alone moves only its candidate's part, so that part alone is projected
                up = theta.copy()
                up[j] += hstep[j]
                if not _close(c.project(up[sl]), up[sl]):
                    up[j] = theta[j] - hstep[j]
                thetas.append(up)
                signs.append(up[j] - theta[j])
        th = np.stack(thetas) if p else np.zeros((3, 0))
        rs = self.residuals(model, th, np.stack([lm, lm + _H, lm] + [lm] * p), np.stack([lu, lu, lu + _H] + [lu] * p))
        return rs, signs

    def _normal(self, rs: np.ndarray, signs: list[float]):
        """Per-object normal-equation blocks from a :meth:`_stencil`'s residuals ``rs`` (3 + p, rows) and steps
        ``signs`` (p,): A (N,2,2), B (N,2,p), C (N,p,p), the gradients g_u (N,2), g_t (N,p), and the residuals."""
        p = len(signs)
        r0 = rs[0]
        jm, ju = self._free_columns((rs[1] - r0) / _H, (rs[2] - r0) / _H)
        step = np.asarray(signs, float)
        moved = step != 0
        jt = np.zeros((p, r0.size))
        jt[moved] = (rs[3:][moved] - r0) / step[moved, None]
        # every product of two columns of [jm, ju, jt, r0] summed object by object in one bincount: each sum runs
        # over the rows in order, as one bincount per product would
        J = np.column_stack([jm, ju, jt.T, r0])
        q = p + 3
        first, second = _pairs(q)
        n, pairs = self.n_obj, first.size
        index = (self._row_obj()[:, None] * pairs + np.arange(pairs)).ravel()
        sums = np.bincount(index, (J[:, first] * J[:, second]).ravel(), minlength=n * pairs).reshape(n, pairs)
        G = np.empty((n, q, q))
        G[:, first, second] = sums
        G[:, second, first] = sums
        A = G[:, :2, :2].copy()
        for a in range(2):
            A[:, a, a] = np.where(A[:, a, a] > 0, A[:, a, a], 1.0)
        B = np.ascontiguousarray(G[:, :2, 2 : 2 + p])
        C = np.ascontiguousarray(G[:, 2 : 2 + p, 2 : 2 + p])
        g_u = np.ascontiguousarray(G[:, :2, q - 1])
        g_t = np.ascontiguousarray(G[:, 2 : 2 + p, q - 1])
        return A, B, C, g_u, g_t, r0


def _close(a: np.ndarray, b: np.ndarray) -> bool:
    """``np.allclose(a, b)`` for finite arrays of a few numbers, in plain floats (the same doubles; the fits ask it
    for every component at every step)."""
    return all(abs(x - y) <= 1e-8 + 1e-5 * abs(y) for x, y in zip(a.tolist(), b.tolist(), strict=True))


@cache
def _pairs(q: int) -> tuple[np.ndarray, np.ndarray]:
    """The index pairs (i <= j) of a q x q symmetric matrix's upper triangle, row by row."""
    return np.triu_indices(q)
