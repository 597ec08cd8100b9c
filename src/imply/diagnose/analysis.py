"""The diagnosis of a push log: where the gap lies, which effects explain it, how far it shrinks.

Steps (on log displacement, and on log stop time where the log has stop times; each
observable's residuals are divided by its noise sd, so sums of squares are chi-squares):

1. Noise and outliers. Replicate pushes (same object, speed and direction) give each
   observable's noise: a robust sd from the median absolute replicate difference, then,
   once outliers are set aside, the pure-error sd. A push whose replicate difference is
   beyond ``outlier_sd`` robust sds is a gross outlier (of the pair, the one farther
   from the baseline fit); so is a push without replicates whose baseline residual is
   that far out, if few are. Outliers are flagged in the report and left out of every
   fit, so they cannot decide the verdict. ``noise_sd`` / ``stop_time_noise_sd`` replace
   the estimates; without replicates or options the residual variance is used.
2. Where: each object's (m, mu) is fitted against the baseline (a measured mass or
   friction is held fixed instead); its displacement residuals are grouped by speed,
   displacement, direction, fitted mass, fitted friction and object, each band's mean
   with a 95% interval across objects.
3. Aliasing: each candidate's change of the pushes per unit magnitude (a secant at half
   its bound), with each object's (log m, log mu) directions projected out. What the
   projection removes is what the per-object fit absorbs: a candidate that loses at
   least ``fit_alias_share`` of its change this way is reported as aliased with the fit,
   naming the parameter that absorbs it (friction, mass, or both) and how measuring it
   would help. A candidate whose projected change at its largest magnitude is below
   ``min_visible`` (RMS, in either observable) is not identifiable; the others form alias
   classes when their projected changes are nearly parallel (|cos| >= ``alias_cos``;
   for two-component candidates the largest canonical correlation).
4. Which: forward selection. Starting from the baseline, every candidate not yet in the
   model is added in turn and the model is refitted jointly (all its effects' parameters
   and every object's mass and friction; :meth:`imply.diagnose.fit.Problem.fit`, started
   from the best point of a scan of the new candidate's range). A candidate qualifies
   when (a) its likelihood-ratio statistic beats the chi-square quantile at
   ``alpha`` / (candidates left) for its number of components, (b) it lowers the
   leave-one-object-out (``folds``) held-out sum of squares, and (c) it explains more
   than the model's own accuracy (its explained mean square per push is above the
   model floor's, :func:`imply.diagnose.effect_tables.model_floor`). The qualifying candidate
   that lowers the held-out sum of squares most is accepted, and the search goes on
   (at most ``max_effects``). The accepted effects are then the verdict if together they
   close at least ``min_share`` of the held-out gap above the noise floor; otherwise the
   verdict is "none of the candidates", with the unexplained residual.
5. How far: the held-out RMS gap in log displacement before and after the accepted
   effects (each object's parameters refitted at the effects fitted without it), the
   share of the gap above the noise floor it closes, and the same for stop times and for
   the objects' anchored disagreement.

Every accepted effect is reported with its magnitude (and azimuth for a tilt or an
anisotropy) and 95% interval from the joint fit's curvature.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from scipy import stats

from imply.diagnose.candidates import Candidate, Model
from imply.diagnose.fit import JointFit, ObjectFit, Problem
from imply.options import Config, option

log = logging.getLogger("imply.diagnose")

NONE = "none"


@dataclass(frozen=True, kw_only=True)
class DiagnosisConfig(Config):
    """Settings of the diagnostic (config ``gap.diagnose``)."""

    config_key: ClassVar[str] = "gap.diagnose"

    grid: int = option(101, doc="(m, mu) grid per axis for the objects' global search (at most 61 used)", minimum=11)
    folds: int = option(0, doc="held-out folds of objects (0: leave one object out)", minimum=0)
    alpha: float = option(
        0.05, doc="family-wise level over the candidates left at each step (Bonferroni)", exclusive_minimum=0,
        exclusive_maximum=1,
    )  # fmt: skip
    alias_cos: float = option(
        0.95, doc="|cos| of projected sensitivities that makes two effects one class", minimum=0, maximum=1
    )
    min_visible: float = option(
        0.005, doc="RMS at an effect's largest magnitude below which it is not identifiable", minimum=0
    )
    fit_alias_share: float = option(
        0.5, doc="report a candidate as aliased with the per-object fit when the fit absorbs this share", minimum=0,
        maximum=1,
    )  # fmt: skip
    noise_sd: float | None = option(None, doc="log d noise sd (null: estimated from the log)", exclusive_minimum=0)
    stop_time_noise_sd: float | None = option(
        None, doc="log stop time noise sd (null: estimated from the log)", exclusive_minimum=0
    )
    model_floor: float | None = option(None, doc="the model's own log d error (null: measured)", minimum=0)
    stop_time_floor: float | None = option(None, doc="the model's own stop time error (null: measured)", minimum=0)
    min_share: float = option(
        0.8, doc="share of the held-out gap above the floor the accepted effects must close", minimum=0, maximum=1
    )
    use_measured: bool = option(True, doc="use weighed masses where the log has them")
    use_stop_time: bool = option(True, doc="use stop_time where the log has it")
    max_effects: int = option(3, doc="effects accepted at most", minimum=0)
    outlier_sd: float = option(
        6.0, doc="replicate disagreement (robust sds) that flags a gross outlier", exclusive_minimum=0
    )
    scan: int = option(7, doc="magnitudes scanned per candidate effect", minimum=2)


@dataclass
class Diagnosis:
    summary: dict
    residuals: dict = field(default_factory=dict)  # arrays for plots


# -- noise and outliers ---------------------------------------------------------------


def _groups(cond: np.ndarray, w: np.ndarray) -> list[np.ndarray]:
    order = np.argsort(cond, kind="stable")
    c = cond[order]
    cuts = np.flatnonzero(np.diff(c)) + 1
    return [g[w[g] > 0] for g in np.split(order, cuts)]


def _replicate_scale(y: np.ndarray, groups: list[np.ndarray]) -> tuple[float | None, int]:
    """Robust noise sd from replicate differences (1.4826 x median |difference| / sqrt 2)."""
    diffs = []
    for g in groups:
        if g.size >= 2:
            vals = y[g]
            diffs.extend(np.abs(vals[:, None] - vals[None, :])[np.triu_indices(g.size, 1)].tolist())
    if len(diffs) < 2:
        return None, len(diffs)
    return float(1.4826 * np.median(diffs) / np.sqrt(2.0)), len(diffs)


def _pure_error(y: np.ndarray, groups: list[np.ndarray]) -> tuple[float, int]:
    ss, df = 0.0, 0
    for g in groups:
        if g.size >= 2:
            ss += float(((y[g] - y[g].mean()) ** 2).sum())
            df += g.size - 1
    return ss, df


def _flag_replicates(y, groups, scale, k, resid) -> np.ndarray:
    """Rows whose replicate disagreement is beyond k robust sds (the member farther from the fit)."""
    flags = np.zeros(y.size, bool)
    if scale is None or scale <= 0:
        return flags
    for g in groups:
        if g.size < 2:
            continue
        if g.size == 2:
            if abs(y[g[0]] - y[g[1]]) > k * np.sqrt(2.0) * scale:
                flags[g[np.argmax(np.abs(resid[g]))]] = True
            continue
        for j in g:
            others = np.median(y[g[g != j]])
            if abs(y[j] - others) > k * np.sqrt(1.0 + 1.0 / (g.size - 1)) * scale:
                flags[j] = True
    return flags


def _flag_singletons(resid, groups, scale, k) -> np.ndarray:
    """Rows without replicates whose residual is beyond k sds, if at most 5% of the pushes are."""
    flags = np.zeros(resid.size, bool)
    if scale is None or scale <= 0:
        return flags
    single = (
        np.concatenate([g for g in groups if g.size == 1]) if any(g.size == 1 for g in groups) else np.zeros(0, int)
    )
    if not single.size:
        return flags
    far = single[np.abs(resid[single]) > k * scale]
    if far.size <= max(1, int(0.05 * resid.size)):
        flags[far] = True
    return flags


def noise_and_outliers(prob: Problem, opts: DiagnosisConfig) -> dict:
    """Each observable's noise sd and the rows flagged as gross outliers (sets them on ``prob``)."""
    n = prob.y.size
    ones = np.ones(n)
    groups = _groups(prob.cond, ones)
    out: dict = {"groups": int(prob.n_cond)}
    # a first baseline fit, on everything, to tell which member of a pair is off
    prob.set_noise(1.0, 1.0)
    prob.set_weights(ones, ones if prob.use_t else None)
    fit0 = prob.initial_fit()
    pd, pt = prob.predict(Model(), np.zeros(0), fit0.lm[prob.c_obj], fit0.lu[prob.c_obj])
    rd, rt = prob.row_residuals(pd, pt)
    weights = {}
    for name, y, r, opt_sd in (("displacement", prob.y, rd, opts.noise_sd),
                                ("stop_time", prob.y_t, rt, opts.stop_time_noise_sd)):  # fmt: skip
        if y is None:
            continue
        scale, npairs = _replicate_scale(y, groups)
        flags = _flag_replicates(y, groups, scale, opts.outlier_sd, r)
        if scale is None:
            # no replicates: a robust scale of the baseline residuals
            med = np.median(np.abs(r - np.median(r)))
            scale_r = 1.4826 * med if med > 0 else None
            flags |= _flag_singletons(r, groups, scale_r, opts.outlier_sd)
        else:
            flags |= _flag_singletons(r, groups, scale, opts.outlier_sd)
        # a flagged push's replicates are set aside too: the kept pushes are then all in complete
        # groups whose spread is the noise the tests assume, with no stray tail among them
        partners = np.isin(prob.cond, prob.cond[flags]) & ~flags
        w = (~(flags | partners)).astype(float)
        ss, df = _pure_error(y, _groups(prob.cond, w))
        info = {"robust_sd": scale, "replicate_pairs": npairs, "pure_error_ss": ss, "pure_error_df": df,
                "outliers": np.flatnonzero(flags).tolist(), "set_aside": np.flatnonzero(partners).tolist()}  # fmt: skip
        if opt_sd is not None:
            info.update(sd=float(opt_sd), source="option")
        elif df >= 2 and ss > 1e-12 * df:
            info.update(sd=float(np.sqrt(ss / df)), source="replicate pushes")
        else:
            keep = w > 0
            dof = max(int(keep.sum()) - prob.k_free * prob.n_obj, 1)
            info.update(sd=float(np.sqrt(np.sum(r[keep] ** 2) / dof)) or 1e-3,
                        source="residual variance (no replicate pushes and no noise option)")  # fmt: skip
        out[name] = info
        weights[name] = w
    prob.set_noise(out["displacement"]["sd"], out.get("stop_time", {}).get("sd"))
    prob.set_weights(weights["displacement"], weights.get("stop_time"))
    return out


# -- where ----------------------------------------------------------------------------


def _band_stats(values: np.ndarray, obj: np.ndarray, n_obj: int) -> dict:
    """Mean residual over objects' band means, with a 95% t interval across objects."""
    per_obj = np.bincount(obj, values, minlength=n_obj)
    cnt = np.bincount(obj, minlength=n_obj)
    means = per_obj[cnt > 0] / cnt[cnt > 0]
    k = means.size
    mean = float(means.mean())
    half = float(stats.t.ppf(0.975, k - 1) * means.std(ddof=1) / np.sqrt(k)) if k >= 2 else float("nan")
    lo, hi = mean - half, mean + half
    return {
        "n_pushes": int(values.size), "n_objects": int(k), "mean": mean, "ci95": [lo, hi],
        "rms": float(np.sqrt(np.mean(values**2))), "differs": bool(np.isfinite(half) and (lo > 0 or hi < 0)),
    }  # fmt: skip


def _bands(x: np.ndarray, n_bins: int, distinct_max: int = 12) -> tuple[np.ndarray, list[str]]:
    uniq = np.unique(x)
    if uniq.size <= distinct_max:
        return np.searchsorted(uniq, x), [f"{u:.4g}" for u in uniq]
    edges = np.quantile(x, np.linspace(0, 1, n_bins + 1))
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, n_bins - 1)
    return idx, [f"[{edges[i]:.4g}, {edges[i + 1]:.4g}]" for i in range(n_bins)]


def localise(prob: Problem, fit: ObjectFit, resid: np.ndarray, alpha: float) -> dict:
    """Displacement residuals of the baseline fit, by region (flagged outliers left out)."""
    keep = prob.w_d > 0
    obj, n_obj = prob.obj[keep], prob.n_obj
    r = resid[keep]
    out: dict = {}
    factors = {
        "speed": _bands(prob.v[keep], 5),
        "displacement": _bands(prob.log.displacement[keep], 5, distinct_max=0),
        "fitted_mass": _bands(np.exp(fit.lm)[obj], 3, distinct_max=0),
        "fitted_friction": _bands(np.exp(fit.lu)[obj], 3, distinct_max=0),
    }
    if prob.log.has_direction:
        sector = np.round(np.mod(prob.phi[keep], 2 * np.pi) / (np.pi / 4)).astype(int) % 8
        uniq = np.unique(sector)
        factors["direction"] = (np.searchsorted(uniq, sector), [f"{s * 45} deg" for s in uniq])
    for name, (idx, labels) in factors.items():
        out[name] = [{"band": label, **_band_stats(r[idx == b], obj[idx == b], n_obj)}
                     for b, label in enumerate(labels) if (idx == b).any()]  # fmt: skip
    sse = np.bincount(obj, r**2, minlength=n_obj)
    sd_row = np.broadcast_to(prob.sd_d, prob.y.shape)[keep]
    wsse = np.bincount(obj, (r / sd_row) ** 2, minlength=n_obj)
    cnt = np.bincount(obj, minlength=n_obj)
    dof = np.maximum(cnt - prob.k_free, 1)
    objs = []
    for i, name in enumerate(prob.log.objects):
        row = {"object_id": name, "n_pushes": int(cnt[i]), "rms": float(np.sqrt(sse[i] / max(cnt[i], 1))),
               "mass_hat": float(np.exp(fit.lm[i])), "friction_hat": float(np.exp(fit.lu[i]))}  # fmt: skip
        p = float(stats.chi2.sf(wsse[i], dof[i]))
        row.update(p_value=p, differs=bool(p < alpha / n_obj))
        objs.append(row)
    out["object"] = objs
    out["regions_beyond_noise"] = [
        f"{name}={row['band']}" for name in factors for row in out[name] if row["differs"]
    ] + [f"object={r['object_id']}" for r in objs if r.get("differs")]
    return out


# -- aliasing -------------------------------------------------------------------------


def _reference(c: Candidate) -> np.ndarray:
    """Half the candidate's largest magnitude, per component (toward the larger side)."""
    ref = np.where(np.abs(np.asarray(c.hi)) >= np.abs(np.asarray(c.lo)), c.hi, c.lo) * 0.5
    if c.radius is not None:
        ref = ref / np.sqrt(2.0)
    return np.asarray(ref, float)


def _projector(prob: Problem, fit: ObjectFit):
    """Functions removing each object's (log m, log mu) directions (both, or each alone) from row vectors."""
    lm, lu = fit.lm[None, :], fit.lu[None, :]
    r = prob.residuals(Model(), np.zeros((3, 0)), np.concatenate([lm, lm + 1e-4, lm]),
                       np.concatenate([lu, lu, lu + 1e-4]))  # fmt: skip
    jm, ju = (r[1] - r[0]) / 1e-4, (r[2] - r[0]) / 1e-4
    jm, ju = prob._free_columns(jm, ju)
    ro = prob._row_obj()
    n = prob.n_obj

    def onto(x: np.ndarray, cols: list[np.ndarray]) -> np.ndarray:
        cols = [c for c in cols if np.any(c != 0)]
        if not cols:
            return x
        k = len(cols)
        A = np.zeros((n, k, k))
        b = np.zeros((n, k))
        for a in range(k):
            b[:, a] = np.bincount(ro, cols[a] * x, minlength=n)
            for c in range(k):
                A[:, a, c] = np.bincount(ro, cols[a] * cols[c], minlength=n)
        A += 1e-12 * np.eye(k)
        coef = np.linalg.solve(A, b[..., None])[..., 0]
        return x - sum(coef[ro, a] * cols[a] for a in range(k))

    return (lambda x: onto(x, [jm, ju])), (lambda x: onto(x, [jm])), (lambda x: onto(x, [ju]))


def _canonical(a: np.ndarray, b: np.ndarray) -> float:
    """Largest canonical correlation between the column spaces of a and b."""
    qa, _ = np.linalg.qr(a)
    qb, _ = np.linalg.qr(b)
    return float(np.linalg.svd(qa.T @ qb, compute_uv=False).max())


def aliasing(prob: Problem, candidates: list[Candidate], fit: ObjectFit, opts: DiagnosisConfig) -> dict:
    """Projected sensitivities, identifiability, alias classes, and aliasing with the per-object fit."""
    both, mass_only, fric_only = _projector(prob, fit)
    n_d = prob.y.size
    lm, lu = fit.lm[None, :], fit.lu[None, :]
    r0 = prob.residuals(Model(), np.zeros((1, 0)), lm, lu)[0]
    rows, vecs = {}, {}
    for c in candidates:
        model = Model((c,))
        ref = _reference(c)
        ths = []
        for j in range(c.dim):
            t = np.zeros(c.dim)
            t[j] = ref[j]
            ths.append(t)
        rr = prob.residuals(model, np.stack(ths), np.repeat(lm, c.dim, 0), np.repeat(lu, c.dim, 0))
        S = np.stack([(rr[j] - r0) / ref[j] for j in range(c.dim)], 1)  # (rows, dim)
        P = np.stack([both(S[:, j]) for j in range(c.dim)], 1)
        ext = float(np.hypot(*c.scale())) if c.radius is None and c.dim == 2 else float(c.radius or c.scale()[0])
        raw2 = float((S**2).sum())
        vis2 = float((P**2).sum())

        def rms_part(M: np.ndarray, part: slice, sd) -> float:
            x = M[part] * np.broadcast_to(sd, (n_d,))[:, None]  # back to log units
            return float(np.sqrt(np.mean((x**2).sum(1)) if x.size else 0.0))

        dpart = slice(0, n_d)
        tpart = slice(n_d, 2 * n_d)
        vis_d = rms_part(P, dpart, prob.sd_d) * ext
        vis_t = rms_part(P, tpart, prob.sd_t) * ext if prob.use_t else 0.0
        absorbed = 1.0 - vis2 / raw2 if raw2 > 0 else 0.0
        by_mass = by_fric = 0.0
        if raw2 > 0:
            if prob.fixed_lm is None:
                by_mass = 1.0 - float(sum((mass_only(S[:, j]) ** 2).sum() for j in range(c.dim))) / raw2
            if prob.fixed_lu is None:
                by_fric = 1.0 - float(sum((fric_only(S[:, j]) ** 2).sum() for j in range(c.dim))) / raw2
        rows[c.name] = {
            "raw_rms_at_bound": rms_part(S, dpart, prob.sd_d) * ext, "visible_rms_at_bound": vis_d,
            "visible_stop_time_rms_at_bound": vis_t if prob.use_t else None,
            "visible_share": 1.0 - absorbed, "absorbed_by_fit": absorbed,
            "absorbed_by_mass": by_mass, "absorbed_by_friction": by_fric,
            "identifiable": bool(max(vis_d, vis_t) >= opts.min_visible),
        }  # fmt: skip
        rows[c.name]["fit_alias"] = _fit_alias_text(c, rows[c.name], prob, opts)
        vecs[c.name] = P
    ident = [c.name for c in candidates if rows[c.name]["identifiable"]]
    cos: dict[str, float] = {}
    parent = {n: n for n in ident}

    def root(n: str) -> str:
        while parent[n] != n:
            n = parent[n]
        return n

    for i, a in enumerate(ident):
        for b in ident[i + 1 :]:
            va, vb = vecs[a], vecs[b]
            if va.shape[1] == 1 and vb.shape[1] == 1:
                cval = float(va[:, 0] @ vb[:, 0] / (np.linalg.norm(va) * np.linalg.norm(vb) + 1e-300))
            else:
                cval = _canonical(va, vb)
            cos[f"{a}|{b}"] = cval
            if abs(cval) >= opts.alias_cos:
                parent[root(b)] = root(a)
    classes: dict[str, list[str]] = {}
    for n in ident:
        classes.setdefault(root(n), []).append(n)
    class_of = {n: "+".join(members) for members in classes.values() for n in members}
    for n in rows:
        rows[n]["class"] = class_of.get(n, "not identifiable")
    return {
        "effects": rows,
        "classes": sorted(set(class_of.values())),
        "not_identifiable": [c.name for c in candidates if not rows[c.name]["identifiable"]],
        "aliased_with_fit": [c.name for c in candidates if rows[c.name]["fit_alias"]],
        "projected_cosine": cos,
    }


_PHRASE = {
    "speed_gain": "a speed gain", "speed_offset": "a speed offset", "viscous": "viscous friction",
    "air_drag": "air drag", "pusher_softness": "a softer pusher", "tilt": "a tilted table",
    "anisotropic": "anisotropic friction", "torsional": "torsional friction", "rolling": "rolling friction",
    "height": "a different box height",
}  # fmt: skip


def _fit_alias_text(c: Candidate, row: dict, prob: Problem, opts: DiagnosisConfig) -> str:
    """A sentence when the per-object (mass, friction) fit absorbs most of what the candidate does."""
    share = row["absorbed_by_fit"]
    if share < opts.fit_alias_share:
        return ""
    what = _PHRASE.get(c.name, c.name)
    fm, ff = row["absorbed_by_mass"], row["absorbed_by_friction"]
    if ff >= opts.fit_alias_share and ff >= fm:
        param, fix = "a friction change", "friction is measured"
    elif fm >= opts.fit_alias_share:
        param, fix = "a mass change", "mass is measured"
    else:
        param = "a change of mass and friction together"
        fix = "mass or friction is measured" if prob.k_free == 2 else "both are measured"
    return (f"{what} here is {share:.0%} indistinguishable from {param} of each object (the per-object fit "
            f"absorbs it) unless {fix}")  # fmt: skip


# -- which ----------------------------------------------------------------------------


def _folds(n_obj: int, k: int) -> np.ndarray:
    if k <= 0 or k >= n_obj:
        return np.arange(n_obj)
    return np.arange(n_obj) % max(2, k)


def _scan_points(c: Candidate, n: int) -> np.ndarray:
    """Starting values of a candidate's components across its range (the origin excluded)."""
    if c.dim == 1:
        lo, hi = c.lo[0], c.hi[0]
        pts = np.linspace(lo, hi, n)
        pts = pts[np.abs(pts) > 1e-12 * max(abs(lo), abs(hi))]
        return pts[:, None]
    r = c.radius
    az = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    out = [np.stack([f * r * np.cos(az), f * r * np.sin(az)], 1) for f in (0.25, 0.6, 1.0)]
    return np.concatenate(out)


def fit_candidate(prob: Problem, base: JointFit, c: Candidate, opts: DiagnosisConfig) -> JointFit:
    """``base``'s model plus ``c``, fitted jointly, started from the best point of a scan of c's range."""
    model = base.model.plus(c)
    pts = _scan_points(c, opts.scan)
    thetas = np.concatenate([np.repeat(base.theta[None, :], len(pts), 0), pts], 1)
    thetas = np.stack([model.project(t) for t in thetas])
    _, _, sse = prob.refine_many(model, thetas, base.objects.lm[None, :], base.objects.lu[None, :], iters=3)
    total = sse.sum(1)
    best = thetas[int(np.argmin(total))]
    start_obj = ObjectFit(base.objects.lm, base.objects.lu, base.objects.sse)
    return prob.fit(model, best, start_obj)


@dataclass
class StepResult:
    candidate: Candidate
    fit: JointFit
    lr: float
    df: int
    critical: float
    heldout_gain: float  # held-out sum of squares (whitened) removed
    heldout_share: float  # of the current model's held-out sum of squares
    explained_ms: float  # explained mean square per push (whitened)
    floor_ms: float
    qualifies: bool
    reasons: list[str]


def _floors(prob: Problem, opts: DiagnosisConfig) -> float:
    """The model's own error as a mean square per push, in whitened units (both observables)."""
    keep = prob.w_d > 0
    md = np.broadcast_to(prob.model_err_d / prob.sd_d, prob.y.shape)[keep]
    out = float(np.mean(md**2)) if keep.any() else 0.0
    if prob.use_t:
        keep_t = prob.w_t > 0
        mt = np.broadcast_to(prob.model_err_t / prob.sd_t, prob.y.shape)[keep_t]
        out += float(np.mean(mt**2)) if keep_t.any() else 0.0
    return out


def numerical_floors(prob: Problem, opts: DiagnosisConfig) -> tuple[float, float]:
    """The simulator's own numerical error per observable (the part of the model floor that is not
    interpolation; interpolation is judged push by push)."""
    floor = (prob.etables.meta.get("model_floor") or {}) if prob.etables is not None else {}
    num_d = floor.get("numerical_rms")
    num_t = (floor.get("stop_time") or {}).get("numerical_rms")
    d = float(num_d) if num_d is not None else float(opts.model_floor or 0.0)
    t = float(num_t) if num_t is not None else float(opts.stop_time_floor or 0.0)
    return d, t


def set_model_error(prob: Problem, jf: JointFit, opts: DiagnosisConfig) -> None:
    """Per-row model error: the simulator's numerical error, the tables' interpolation where the model
    reads them (|cubic - linear|), and the model's tabulated effects (their measured relative error)."""
    num_d, num_t = numerical_floors(prob, opts)
    ind_d, ind_t = prob.interpolation_indicator(jf.objects, jf.model, jf.theta)
    err_d2 = num_d**2 + ind_d**2
    err_t2 = num_t**2 + ind_t**2 if ind_t is not None else None
    if jf.model.dim:
        # a speed or friction carried outside the table's range is extrapolated: count its size as error
        _, _, (ext_d, ext_t) = prob.predict(jf.model, jf.theta, jf.objects.lm[prob.c_obj], jf.objects.lu[prob.c_obj],
                                            extrapolation=True)  # fmt: skip
        err_d2 = err_d2 + ext_d[prob.cond] ** 2
        if err_t2 is not None and ext_t is not None:
            err_t2 = err_t2 + ext_t[prob.cond] ** 2
    lm_c, lu_c = jf.objects.lm[prob.c_obj], jf.objects.lu[prob.c_obj]
    if jf.model.dim and prob.etables is not None:
        for key, dd, dt in prob.table_terms(jf.model, jf.theta, lm_c, lu_c):
            # a table's error relative to the effect it carries, as measured (at most the effect itself)
            err_d2 = err_d2 + (min(prob.etables.relative_error(key, "d"), 1.0) * dd)[prob.cond] ** 2
            if err_t2 is not None and dt is not None:
                err_t2 = err_t2 + (min(prob.etables.relative_error(key, "t"), 1.0) * dt)[prob.cond] ** 2
    prob.set_model_error(np.sqrt(err_d2), None if err_t2 is None else np.sqrt(err_t2))


def forward_select(prob: Problem, base: JointFit, candidates: list[Candidate], alias: dict, opts: DiagnosisConfig):
    """Add candidates while each still qualifies; return (final fit, steps: [[StepResult]], accepted)."""
    folds = _folds(prob.n_obj, opts.folds)
    current = base
    accepted: list[Candidate] = []
    steps: list[list[StepResult]] = []
    pool = [c for c in candidates if alias["effects"][c.name]["identifiable"]]
    n = max(prob.n_rows, 1)
    for _ in range(max(opts.max_effects, 0)):
        taken_classes = {alias["effects"][a.name]["class"] for a in accepted}
        left = [c for c in pool if c not in accepted and alias["effects"][c.name]["class"] not in taken_classes]
        if not left:
            break
        floor_ms = _floors(prob, opts)
        cv0 = current.heldout_sse_quadratic(folds).sum()
        results = []
        for c in left:
            jf = fit_candidate(prob, current, c, opts)
            lr = max(current.sse - jf.sse, 0.0)
            crit = float(stats.chi2.ppf(1 - opts.alpha / len(left), c.dim))
            cv1 = jf.heldout_sse_quadratic(folds).sum()
            gain = float(cv0 - cv1)
            explained = lr / n
            reasons = []
            if lr <= crit:
                reasons.append(f"likelihood ratio {lr:.1f} <= {crit:.1f}")
            if gain <= 0:
                reasons.append("does not lower the held-out sum of squares")
            if explained <= floor_ms:
                reasons.append("explains less than the model's own accuracy")
            results.append(StepResult(c, jf, lr, c.dim, crit, gain, gain / cv0 if cv0 > 0 else 0.0, explained,
                                      floor_ms, not reasons, reasons))  # fmt: skip
            log.debug("%-16s LR %.1f (crit %.1f) held-out -%.1f explained %.3g (floor %.3g)", c.name, lr, crit,
                      gain, explained, floor_ms)  # fmt: skip
        results.sort(key=lambda r: (-r.heldout_gain, r.candidate.name))
        steps.append(results)
        ok = [r for r in results if r.qualifies]
        if not ok:
            break
        accepted.append(ok[0].candidate)
        current = ok[0].fit
        # the accepted effects' own tables are only so accurate: count it, and refit under it (the
        # objects searched globally again: an accepted effect can move their optimum far)
        set_model_error(prob, current, opts)
        current = prob.fit(current.model, current.theta, prob.initial_fit(current.model, current.theta, n_grid=31))
    return current, steps, accepted


# -- how far --------------------------------------------------------------------------


def heldout(prob: Problem, jf: JointFit, opts: DiagnosisConfig) -> dict:
    """Each object's residuals at the effects fitted without its fold (objects refitted there)."""
    folds = _folds(prob.n_obj, opts.folds)
    model = jf.model
    if model.dim == 0:
        lm, lu = jf.objects.lm, jf.objects.lu
        th_obj = np.zeros((prob.n_obj, 0))
    else:
        per_fold = jf.leave_out(folds)
        keys = sorted(per_fold)
        thetas = np.stack([per_fold[k] for k in keys])
        lms, lus, _ = prob.refine_many(model, thetas, jf.objects.lm[None, :], jf.objects.lu[None, :], iters=6)
        which = np.searchsorted(keys, folds)
        lm = lms[which, np.arange(prob.n_obj)]
        lu = lus[which, np.arange(prob.n_obj)]
        th_obj = thetas[which]
    th_c = th_obj[prob.c_obj] if model.dim else np.zeros(0)
    pd, pt = prob.predict(model, th_c, lm[prob.c_obj], lu[prob.c_obj])
    rd, rt = prob.row_residuals(pd, pt)
    return {"resid_d": rd, "resid_t": rt, "lm": lm, "lu": lu}


def _rms(x: np.ndarray, w: np.ndarray) -> float:
    keep = w > 0
    return float(np.sqrt(np.mean(x[keep] ** 2))) if keep.any() else float("nan")


def _share(before: float, after: float, floor: float | None) -> float | None:
    if floor is None or not np.isfinite(before) or before - floor <= 1e-12:
        return None
    return float((before - after) / (before - floor))


# -- reporting helpers ----------------------------------------------------------------


def effect_report(c: Candidate, theta: np.ndarray, cov: np.ndarray) -> dict:
    """Magnitude (and azimuth) with 95% intervals from the fit's covariance (delta method)."""
    z = 1.959964
    theta = np.asarray(theta, float)
    out: dict = {"effect": c.name, "title": c.title, "unit": c.unit, "components": dict(zip(c.components,
                 theta.tolist(), strict=True))}  # fmt: skip
    if c.dim == 1:
        sd = float(np.sqrt(max(cov[0, 0], 0.0)))
        lo, hi = c.lo[0], c.hi[0]
        out.update(magnitude=float(theta[0]), ci95=[float(max(theta[0] - z * sd, lo)), float(min(theta[0] + z * sd, hi))],
                   sd=sd, at_bound=bool(np.isclose(theta[0], lo) or np.isclose(theta[0], hi)))  # fmt: skip
        return out
    a = float(np.hypot(*theta))
    g = theta / a if a > 0 else np.array([1.0, 0.0])
    sd_a = float(np.sqrt(max(g @ cov @ g, 0.0)))
    if a > 0:
        ga = np.array([-theta[1], theta[0]]) / a**2
        sd_ang = float(np.sqrt(max(ga @ cov @ ga, 0.0)))
    else:
        sd_ang = float("inf")
    ang = c.azimuth(theta)
    factor = 0.5 if c.period and c.period < 2 * np.pi - 1e-9 else 1.0
    half = min(z * sd_ang * factor, c.period / 2)
    out.update(magnitude=a, ci95=[max(a - z * sd_a, 0.0), min(a + z * sd_a, float(c.radius))], sd=sd_a,
               azimuth_deg=float(np.degrees(ang)), azimuth_ci95_deg=[float(np.degrees(ang - half)),
               float(np.degrees(ang + half))], at_bound=bool(a >= c.radius * (1 - 1e-6)))  # fmt: skip
    return out


def verdict_sentence(effects: list[dict], share: float | None) -> str:
    """The verdict in one sentence a lab engineer can act on."""
    parts = []
    by_name = {e["effect"]: e["magnitude"] for e in effects}
    for e in effects:
        m, name = e["magnitude"], e["effect"]
        if name in ("speed_gain", "speed_offset") and {"speed_gain", "speed_offset"} <= set(by_name):
            if name == "speed_offset":
                continue  # said once, with the gain
            g, c = by_name["speed_gain"], by_name["speed_offset"]
            text = f"the pusher's speed is (1 {g:+.1%}) times the command {c:+.3g} m/s"
            if g * c < 0:  # the two cross: slower on one side of a speed, faster on the other
                cross = -c / g
                below, above = ("slower", "faster") if g > 0 else ("faster", "slower")
                text += f" ({below} than commanded below {cross:.2g} m/s, {above} above)"
            parts.append(text)
        elif name == "tilt":
            parts.append(
                f"the table slopes {m:.3g} rad toward {round(e['azimuth_deg']) % 360:.0f} degrees (table frame)"
            )
        elif name == "anisotropic":
            # an axis: 0 and 180 degrees are the same direction
            parts.append(f"friction is {m:.0%} higher along {round(e['azimuth_deg']) % 180:.0f} degrees than across it")
        elif name == "speed_gain":
            parts.append(f"the pusher runs {abs(m):.1%} {'faster' if m > 0 else 'slower'} than commanded")
        elif name == "speed_offset":
            parts.append(f"the pusher runs {abs(m):.3g} m/s {'faster' if m > 0 else 'slower'} than commanded")
        elif name == "viscous":
            parts.append(f"the box feels viscous friction of {m:.3g} N s/m")
        elif name == "air_drag":
            parts.append(f"the box feels air drag as of a medium of {m:.3g} kg/m^3")
        elif name == "pusher_softness":
            parts.append(f"the pusher's contact is softer (solref time constant +{m:.3g} s)")
        elif name == "height":
            parts.append(f"the boxes are {abs(m):.0%} {'taller' if m > 0 else 'shorter'} than the table's")
        else:
            parts.append(f"{e['title']} of {m:.3g} {e['unit']}")
    text = "; ".join(parts)
    text = text[0].upper() + text[1:]
    if share is not None and share >= 1.0:
        # held out, the residual can land a little below the noise floor: the whole gap is closed
        text += f"; adding {'it' if len(effects) == 1 else 'them'} closes the whole gap, down to the noise."
    elif share is not None:
        text += f"; adding {'it' if len(effects) == 1 else 'them'} closes {max(share, 0.0):.0%} of the gap."
    else:
        text += "."
    return text


def _step_rows(results: list[StepResult], alias: dict, model_before: Model, n: int) -> list[dict]:
    rows = []
    k0 = model_before.dim
    for r in results:
        c = r.candidate
        th = r.fit.theta[k0 : k0 + c.dim]
        cov = r.fit.covariance()[k0 : k0 + c.dim, k0 : k0 + c.dim]
        row = effect_report(c, th, cov)
        row.update(
            cls=alias["effects"][c.name]["class"], identifiable=alias["effects"][c.name]["identifiable"],
            lr_stat=r.lr, df=r.df, lr_critical=r.critical, heldout_gain=r.heldout_gain,
            heldout_improvement=r.heldout_share, explained_ms=r.explained_ms, floor_ms=r.floor_ms,
            qualifies=r.qualifies, reasons=r.reasons, delta_bic=float(-r.lr + c.dim * np.log(max(n, 2))),
        )  # fmt: skip
        row["class"] = row.pop("cls")
        rows.append(row)
    return rows


def diagnose(prob: Problem, candidates: list[Candidate], opts: DiagnosisConfig) -> Diagnosis:
    """Run every step on a prepared :class:`Problem`."""
    t0 = time.perf_counter()
    noise = noise_and_outliers(prob, opts)
    fit0 = prob.initial_fit()
    set_model_error(prob, JointFit(Model(), np.zeros(0), fit0, np.zeros((prob.n_obj, 0, 0)), np.zeros((prob.n_obj, 0))),
                    opts)  # fmt: skip
    base = prob.fit(Model(), np.zeros(0), prob.initial_fit())
    objs0 = base.objects
    pd0, pt0 = prob.predict(Model(), np.zeros(0), objs0.lm[prob.c_obj], objs0.lu[prob.c_obj])
    rd0, rt0 = prob.row_residuals(pd0, pt0)
    where = localise(prob, objs0, rd0, opts.alpha)
    alias = aliasing(prob, candidates, objs0, opts)
    final, steps, accepted = forward_select(prob, base, candidates, alias, opts)

    n, N, k = prob.n_rows, prob.n_obj, prob.k_free
    sd = prob.noise_d
    floor = sd * np.sqrt(max(n - k * N, 0) / n) if n else None
    rms0 = _rms(rd0, prob.w_d)
    held = heldout(prob, final, opts)
    rms1 = _rms(held["resid_d"], prob.w_d)
    gap_share = _share(rms0, rms1, floor)
    # both observables, whitened: what the verdict's adequacy is judged on
    ro_w = np.concatenate([prob.w_d, prob.w_t]) if prob.use_t else prob.w_d
    rw0 = np.concatenate([rd0 / prob.sd_d, rt0 / prob.sd_t]) if prob.use_t else rd0 / prob.sd_d
    rw1 = (np.concatenate([held["resid_d"] / prob.sd_d, held["resid_t"] / prob.sd_t]) if prob.use_t
           else held["resid_d"] / prob.sd_d)  # fmt: skip
    nw = int((ro_w > 0).sum())
    # whitened by noise and model error together: an adequate model leaves unit variance
    floor_w = float(np.sqrt(max(nw - k * N * (2 if prob.use_t else 1), 0) / nw)) if nw else None
    both_share = _share(_rms(rw0, ro_w), _rms(rw1, ro_w), floor_w)
    stop_share = None
    if prob.use_t:
        floor_t = prob.noise_t * np.sqrt(max(n - k * N, 0) / n)
        stop_share = _share(_rms(rt0, prob.w_t), _rms(held["resid_t"], prob.w_t), floor_t)

    # lack of fit of the accepted model, held out: at the noise and the model's own error an
    # adequate model leaves a chi-square; overdispersion also widens the effects' intervals
    keep_w = ro_w > 0
    lof_ss = float(np.sum((rw1[keep_w]) ** 2))
    lof_dof = max(nw - k * N - final.model.dim, 1)
    lof = {"heldout_chi2": lof_ss, "dof": lof_dof, "p_value": float(stats.chi2.sf(lof_ss, lof_dof)),
           "in_sample_chi2": final.sse, "baseline_chi2": float(np.sum(rw0[keep_w] ** 2))}  # fmt: skip
    for name, r0, r1, w in (("displacement", rd0 / prob.sd_d, held["resid_d"] / prob.sd_d, prob.w_d),
                            ("stop_time", rt0 / prob.sd_t if prob.use_t else None,
                             held["resid_t"] / prob.sd_t if prob.use_t else None, prob.w_t)):  # fmt: skip
        if r0 is not None:
            kk = w > 0
            lof[name] = {"baseline_chi2": float(np.sum(r0[kk] ** 2)), "heldout_chi2": float(np.sum(r1[kk] ** 2)),
                         "n": int(kk.sum())}  # fmt: skip
    dispersion = max(final.sse / max(nw - k * N - final.model.dim, 1), 1.0)
    cov = final.covariance() * dispersion
    reported = [effect_report(c, final.theta[sl], cov[sl, sl]) for c, sl in zip(final.model.candidates,
                final.model.slices(), strict=True)]  # fmt: skip
    for e in reported:
        e["class"] = alias["effects"][e["effect"]]["class"]
        e["fit_alias"] = alias["effects"][e["effect"]]["fit_alias"]
    judged = both_share if both_share is not None else gap_share
    if not accepted:
        first = steps[0] if steps else []
        any_gap = any(r.lr > r.critical for r in first)
        reason = ("no candidate improves the fit beyond noise and the model's own accuracy" if any_gap
                  else "no gap beyond noise")  # fmt: skip
        verdict = {"verdict": NONE, "effects": [], "class": None, "effect": None, "reason": reason, "partial": None}
    elif judged is not None and judged < opts.min_share:
        verdict = {"verdict": NONE, "effects": [], "class": None, "effect": None, "partial": "+".join(final.model.names),
                   "reason": f"the best candidates ({' + '.join(final.model.names)}) close only {judged:.0%} of the "
                             "gap above the noise floor"}  # fmt: skip
    else:
        verdict = {"verdict": "; ".join(e["class"] for e in reported), "effects": [e["effect"] for e in reported],
                   "class": reported[0]["class"], "effect": reported[0]["effect"], "reason": "improves beyond noise",
                   "partial": None}  # fmt: skip
    verdict["lr_critical"] = steps[0][0].critical if steps and steps[0] else None

    unexplained = float(np.sqrt(max(rms1**2 - floor**2, 0.0))) if floor is not None else rms1
    if verdict["verdict"] != NONE:
        # the share the verdict was judged on (both observables, whitened), as the "none" sentences quote it
        sentence = verdict_sentence(reported, judged if judged is not None else gap_share)
    elif verdict["partial"]:
        sentence = (f"None of the candidate effects explains the gap: the best combination "
                    f"({' + '.join(final.model.names)}) closes only {max(judged or 0, 0):.0%} of it, and "
                    f"{unexplained:.3g} RMS log d remains above the noise floor; look for an effect outside the "
                    "library.")  # fmt: skip
    elif verdict["reason"] == "no gap beyond noise":
        sentence = (f"No gap beyond noise: the table agrees with these pushes within their noise "
                    f"(RMS residual {rms0:.3g} against a noise floor of {floor:.3g} in log d).")  # fmt: skip
    else:
        sentence = (f"None of the candidate effects explains the gap ({unexplained:.3g} RMS log d above the noise "
                    "floor); look for an effect outside the library.")  # fmt: skip
    verdict["sentence"] = sentence

    anch0 = np.sqrt(np.bincount(prob.obj, (prob.w_d * rd0) ** 2, minlength=N) / np.maximum(prob.counts, 1))
    anch1 = np.sqrt(np.bincount(prob.obj, (prob.w_d * held["resid_d"]) ** 2, minlength=N) / np.maximum(prob.counts, 1))
    anch_floor = float(np.mean(sd * np.sqrt(np.maximum(prob.counts - k, 0) / np.maximum(prob.counts, 1))))
    shrink = {
        "effects": final.model.names if verdict["verdict"] != NONE or verdict["partial"] else [],
        "effect": "+".join(final.model.names) or None,
        "before_rms": rms0, "after_rms": rms1, "noise_floor_rms": floor, "gap_share_closed": gap_share,
        "stop_time_share_closed": stop_share, "both_share_closed": both_share,
        "lack_of_fit": lof, "dispersion": dispersion,
        "anchored_before_mean": float(anch0.mean()), "anchored_after_mean": float(anch1.mean()),
        "anchored_floor": anch_floor, "anchored_share_closed": _share(float(anch0.mean()), float(anch1.mean()),
                                                                     anch_floor),
        "unexplained_rms_above_floor": unexplained,
    }  # fmt: skip
    ranking = _step_rows(steps[0], alias, Model(), n) if steps else []
    path = []
    model_before = Model()
    for j, res in enumerate(steps):
        chosen = accepted[j].name if j < len(accepted) else None
        path.append({"step": j + 1, "accepted": chosen, "model_before": model_before.names,
                     "candidates": _step_rows(res, alias, model_before, n)})  # fmt: skip
        if chosen:
            model_before = model_before.plus(accepted[j])
    outliers = {name: [{"row": int(i), "object_id": prob.log.objects[prob.obj[i]], "speed": float(prob.v[i]),
                        "direction": float(prob.phi[i])} for i in noise[name]["outliers"]]
                for name in ("displacement", "stop_time") if name in noise}  # fmt: skip
    observables = ["displacement"] + (["stop_time"] if prob.use_t else [])
    if prob.log.stop_time is not None and not prob.use_t:
        obs_note = "displacement only (the log's stop times were not used)"
    elif prob.use_t:
        obs_note = "displacement and stop time: every candidate had to explain both"
    else:
        obs_note = "displacement only (the log has no stop_time)"
    summary = {
        "pushlog": prob.log.path,
        "n_pushes": int(prob.y.size), "n_objects": int(N), "has_direction": prob.log.has_direction,
        "measured": {"mass": prob.fixed_lm is not None, "friction": prob.fixed_lu is not None},
        "observables": observables, "observables_note": obs_note,
        "noise": {k2: v for k2, v in noise.items() if k2 != "groups"} | {"sd": prob.noise_d,
                  "stop_time_sd": prob.noise_t if prob.use_t else None,
                  "source": noise["displacement"]["source"]},
        "outliers": outliers,
        "n_outliers": int(sum(len(v) for v in outliers.values())),
        "baseline": {"rms": rms0, "sse_whitened": base.sse},
        "localisation": where,
        "aliasing": alias,
        "ranking": ranking,
        "selection": path,
        "effects": reported,
        "verdict": verdict,
        "shrinkage": shrink,
        "options": opts.to_dict(),
        "model_floor": prob.etables.meta.get("model_floor") if prob.etables is not None else None,
        "seconds": round(time.perf_counter() - t0, 3),
    }  # fmt: skip
    resid = {"speed": prob.v, "direction": prob.phi, "log_d": prob.y, "resid_before": rd0,
             "resid_after": held["resid_d"] if final.model.dim else None, "flagged": prob.w_d == 0,
             "stop_resid_before": rt0, "stop_resid_after": held["resid_t"] if final.model.dim else None}  # fmt: skip
    return Diagnosis(summary=summary, residuals=resid)
