"""The diagnosis of a push log: where the gap lies, which effect explains it, how far it shrinks.

Steps (all on log displacement):

1. Noise: ``noise_sd`` from the options if given; else the pure-error variance of
   replicate pushes (same object, speed and direction) if the log has any that differ;
   else unknown (tests then use the residual variance).
2. Where: each object's (m, mu) is fitted against the baseline table (a measured mass
   or friction is held fixed instead); its residuals are
   grouped by speed, displacement, direction, fitted mass, fitted friction and object.
   A band's mean residual gets a 95% interval across objects (each object's mean in
   the band is one observation, so within-object correlation does not shrink it); a
   band differs from zero when its interval excludes 0. Objects are flagged when their
   residual is beyond a chi-square bound at the noise (Bonferroni over objects).
3. Aliasing: each effect's change of log d per unit magnitude (a secant from 0 to a
   reference magnitude) at every push, with each object's (log m, log mu) directions
   projected out. An effect whose projected change at its largest magnitude is below
   ``min_visible`` (RMS log d) is not identifiable from these pushes; the others are
   grouped into one class when their projected changes are nearly parallel
   (|cos| >= ``alias_cos``).
4. Which: for each effect, a global magnitude is profiled over its bounds with every
   object's (m, mu) refitted; the magnitude minimises the summed squared residual, its
   95% interval is the profile-likelihood interval at the noise variance. Held-out
   improvement: objects are split into folds; the magnitude is fitted on the other
   folds and the held-out objects' squared residual (their own (m, mu) refitted at that
   magnitude) is compared with the baseline's. An effect beats noise when its
   likelihood-ratio statistic exceeds the chi-square(1) quantile at alpha / (number of
   candidates) and its held-out residual is lower than the baseline's. The top effect is
   accepted as the cause when, in addition, it changes log d by more than the table's own
   accuracy (``model_floor``: RMS explained > floor) and closes at least ``min_share`` of
   the held-out RMS gap above the noise floor; otherwise the answer is "none of the
   candidates", with the unexplained residual (and the best partial candidate named).
   A lack-of-fit F test against the pure error is reported for every candidate.
   Speed effects are searched only where every actual speed stays inside the table.
5. How far: the held-out RMS gap before and after adding the top effect, the share of
   the gap above the noise floor it closes, and the same for the objects' anchored
   disagreement (the RMS residual of each object's joint (m, mu) fit over all its pushes,
   calibration and rollouts alike).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from scipy import stats
from scipy.interpolate import PchipInterpolator

from imply.diagnose.fit import ObjectFit, Problem
from imply.options import Config
from imply.sim.effects import SPEED, Effect

log = logging.getLogger("imply.diagnose")

NONE = "none"


@dataclass(frozen=True, kw_only=True)
class DiagnosisConfig(Config):
    """Settings of the diagnostic (config ``gap.diagnose``)."""

    config_key: ClassVar[str] = "gap.diagnose"

    grid: int = 101
    n_profile: int = 11
    folds: int = 5
    alpha: float = 0.05
    alias_cos: float = 0.95
    min_visible: float = 0.005
    noise_sd: float | None = None
    model_floor: float | None = None
    min_share: float = 0.5
    use_measured: bool = True
    fine: int = 401


@dataclass
class Diagnosis:
    summary: dict
    residuals: dict = field(default_factory=dict)  # arrays for plots


def _noise(prob: Problem, opts: DiagnosisConfig) -> dict:
    key = np.stack([prob.obj.astype(float), prob.v, np.round(prob.phi, 6)], axis=1)
    _, group = np.unique(key, axis=0, return_inverse=True)
    group = group.ravel()
    ng = group.max() + 1
    cnt = np.bincount(group, minlength=ng)
    mean = np.bincount(group, prob.y, minlength=ng) / cnt
    ss = float(((prob.y - mean[group]) ** 2).sum())
    df = int((cnt - 1).sum())
    out = {"groups": int(ng), "pure_error_df": df, "pure_error_ss": ss, "group": group}
    if opts.noise_sd is not None:
        out.update(sd=float(opts.noise_sd), source="option noise_sd")
    elif df >= 2 and ss > 1e-12 * df:
        out.update(sd=float(np.sqrt(ss / df)), source="replicate pushes")
    else:
        out.update(sd=None, source="unknown (no replicate pushes and no noise_sd)")
    return out


def _band_stats(values: np.ndarray, obj: np.ndarray, n_obj: int) -> dict:
    """Mean residual over objects' band means, with a 95% t interval across objects."""
    per_obj = np.bincount(obj, values, minlength=n_obj)
    cnt = np.bincount(obj, minlength=n_obj)
    means = per_obj[cnt > 0] / cnt[cnt > 0]
    k = means.size
    mean = float(means.mean())
    if k >= 2:
        half = float(stats.t.ppf(0.975, k - 1) * means.std(ddof=1) / np.sqrt(k))
    else:
        half = float("nan")
    lo, hi = mean - half, mean + half
    return {
        "n_pushes": int(values.size), "n_objects": int(k), "mean": mean, "ci95": [lo, hi],
        "rms": float(np.sqrt(np.mean(values**2))), "differs": bool(np.isfinite(half) and (lo > 0 or hi < 0)),
    }  # fmt: skip


def _bands(x: np.ndarray, n_bins: int, distinct_max: int = 12) -> tuple[np.ndarray, list[str]]:
    uniq = np.unique(x)
    if uniq.size <= distinct_max:
        idx = np.searchsorted(uniq, x)
        return idx, [f"{u:.4g}" for u in uniq]
    edges = np.quantile(x, np.linspace(0, 1, n_bins + 1))
    idx = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, n_bins - 1)
    return idx, [f"[{edges[i]:.4g}, {edges[i + 1]:.4g}]" for i in range(n_bins)]


def localise(
    prob: Problem,
    fit: ObjectFit,
    resid: np.ndarray,
    noise_sd: float | None,
    alpha: float,
) -> dict:
    """Residuals of the baseline fit, by region."""
    obj, n_obj = prob.obj, prob.n_obj
    out: dict = {}
    factors = {
        "speed": _bands(prob.v, 5),
        "displacement": _bands(prob.log.displacement, 5, distinct_max=0),
        "fitted_mass": _bands(np.exp(fit.lm)[obj], 3, distinct_max=0),
        "fitted_friction": _bands(np.exp(fit.lu)[obj], 3, distinct_max=0),
    }
    if prob.log.has_direction:
        sector = np.round(np.mod(prob.phi, 2 * np.pi) / (np.pi / 4)).astype(int) % 8
        uniq = np.unique(sector)
        factors["direction"] = (
            np.searchsorted(uniq, sector),
            [f"{s * 45} deg" for s in uniq],
        )
    for name, (idx, labels) in factors.items():
        rows = []
        for b, label in enumerate(labels):
            sel = idx == b
            if sel.any():
                rows.append({"band": label, **_band_stats(resid[sel], obj[sel], n_obj)})
        out[name] = rows
    # objects: residual beyond noise (chi-square with K - (free parameters) degrees of freedom)
    sse = np.bincount(obj, resid**2, minlength=n_obj)
    dof = np.maximum(prob.counts - prob.k_free, 1)
    objs = []
    for i, name in enumerate(prob.log.objects):
        row = {
            "object_id": name, "n_pushes": int(prob.counts[i]), "rms": float(np.sqrt(sse[i] / prob.counts[i])),
            "mass_hat": float(np.exp(fit.lm[i])), "friction_hat": float(np.exp(fit.lu[i])),
        }  # fmt: skip
        if noise_sd:
            p = float(stats.chi2.sf(sse[i] / noise_sd**2, dof[i]))
            row.update(p_value=p, differs=bool(p < alpha / n_obj))
        objs.append(row)
    out["object"] = objs
    out["regions_beyond_noise"] = [
        f"{name}={row['band']}" for name in factors for row in out[name] if row["differs"]
    ] + [f"object={r['object_id']}" for r in objs if r.get("differs")]
    return out


def _secant(prob: Problem, effect: Effect, fit: ObjectFit) -> tuple[np.ndarray, float]:
    lo, hi = _bounds(prob, effect)
    ref = 0.5 * (hi if abs(hi) >= abs(lo) else lo)
    base = prob.predict(None, 0.0, fit)
    if ref == 0.0:
        return np.zeros_like(base), 0.0
    return (prob.predict(effect, ref, fit) - base) / ref, max(abs(lo), abs(hi))


def aliasing(prob: Problem, effects: list[Effect], fit: ObjectFit, opts: DiagnosisConfig) -> dict:
    """Projected sensitivities, identifiability and alias classes of the effects."""
    obj, P = prob.obj, prob.obj.size
    lm, lu = fit.lm[obj], fit.lu[obj]
    f = prob.predict_push(None, 0.0, np.concatenate([lm, lm + 1e-4, lm]), np.concatenate([lu, lu, lu + 1e-4]),
                          np.concatenate([np.arange(P)] * 3))  # fmt: skip
    jm, ju = (f[P : 2 * P] - f[:P]) / 1e-4, (f[2 * P :] - f[:P]) / 1e-4

    def project(x: np.ndarray) -> np.ndarray:
        # remove each object's (log m, log mu) directions (least squares within each object)
        a11 = np.bincount(obj, jm * jm, minlength=prob.n_obj)
        a12 = np.bincount(obj, jm * ju, minlength=prob.n_obj)
        a22 = np.bincount(obj, ju * ju, minlength=prob.n_obj)
        b1 = np.bincount(obj, jm * x, minlength=prob.n_obj)
        b2 = np.bincount(obj, ju * x, minlength=prob.n_obj)
        if prob.fixed_lm is not None or prob.fixed_lu is not None:
            # one free direction per object (or none): project on it alone
            if prob.k_free == 0:
                return x
            a, b, j = (a22, b2, ju) if prob.fixed_lm is not None else (a11, b1, jm)
            c = np.where(a > 1e-18, b / np.where(a > 1e-18, a, 1.0), 0.0)
            return x - c[obj] * j
        det = a11 * a22 - a12 * a12
        det = np.where(np.abs(det) > 1e-18, det, np.inf)
        c1 = (a22 * b1 - a12 * b2) / det
        c2 = (a11 * b2 - a12 * b1) / det
        return x - c1[obj] * jm - c2[obj] * ju

    rows, vecs = {}, {}
    for e in effects:
        s, ext = _secant(prob, e, fit)
        sp = project(s)
        raw = float(np.sqrt(np.mean(s**2)))
        vis = float(np.sqrt(np.mean(sp**2)))
        rows[e.name] = {
            "raw_rms_at_bound": raw * ext, "visible_rms_at_bound": vis * ext,
            "visible_share": vis / raw if raw > 0 else 0.0,
            "identifiable": bool(vis * ext >= opts.min_visible),
        }  # fmt: skip
        vecs[e.name] = sp
    ident = [e.name for e in effects if rows[e.name]["identifiable"]]
    cos = {}
    parent = {n: n for n in ident}

    def root(n: str) -> str:
        while parent[n] != n:
            n = parent[n]
        return n

    for i, a in enumerate(ident):
        for b in ident[i + 1 :]:
            va, vb = vecs[a], vecs[b]
            c = float(va @ vb / (np.linalg.norm(va) * np.linalg.norm(vb)))
            cos[f"{a}|{b}"] = c
            if abs(c) >= opts.alias_cos:
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
        "not_identifiable": [e.name for e in effects if not rows[e.name]["identifiable"]],
        "projected_cosine": cos,
    }


def _folds(n_obj: int, k: int) -> np.ndarray:
    # deterministic: objects dealt round-robin in order of first appearance
    return np.arange(n_obj) % max(2, min(k, n_obj))


def _bounds(prob: Problem, effect: Effect) -> tuple[float, float]:
    """The effect's bounds, narrowed so that actual speeds stay inside the table (no extrapolation)."""
    lo, hi = effect.bounds
    if effect.kind == SPEED:
        vmin, vmax = prob.v_range
        v0, v1 = float(prob.v.min()), float(prob.v.max())
        if effect.name == "speed_gain":
            lo, hi = max(lo, vmin / v0 - 1.0), min(hi, vmax / v1 - 1.0)
        else:
            lo, hi = max(lo, vmin - v0), min(hi, vmax - v1)
        lo, hi = min(lo, 0.0), max(hi, 0.0)
    return lo, hi


def evaluate_effect(prob: Problem, effect: Effect, start: ObjectFit, opts: DiagnosisConfig, sigma2: float | None,
                    base_sse: np.ndarray, folds: np.ndarray) -> dict:  # fmt: skip
    lo, hi = _bounds(prob, effect)
    grid = np.unique(np.concatenate([np.linspace(lo, hi, opts.n_profile), [0.0]]))
    sse, fits = prob.profile(effect, grid, start)  # (G, N)
    fine = np.linspace(lo, hi, opts.fine)
    curve = PchipInterpolator(grid, sse, axis=0)(fine)  # (F, N)
    total = curve.sum(1)
    j = int(np.argmin(total))
    theta = float(fine[j])
    n = prob.obj.size
    s2 = sigma2 if sigma2 else float(total[j] / max(n - prob.k_free * prob.n_obj - 1, 1))
    inside = fine[total - total[j] <= stats.chi2.ppf(0.95, 1) * s2]
    sse0 = float(base_sse.sum())
    # held-out: fit on the other folds, evaluate on this fold
    held = np.empty(prob.n_obj)
    theta_fold = {}
    for f in np.unique(folds):
        train = folds != f
        jf = int(np.argmin(curve[:, train].sum(1)))
        theta_fold[int(f)] = float(fine[jf])
        held[~train] = curve[jf, ~train]
    cv = float(held.sum())
    lr = (sse0 - float(total[j])) / s2
    at = int(np.argmin(np.abs(grid - theta)))
    return {
        "effect": effect.name, "title": effect.title, "unit": effect.unit, "magnitude": theta,
        "ci95": [float(inside.min()), float(inside.max())],
        "at_bound": bool(j in (0, fine.size - 1) and theta != 0.0),
        "sse": float(total[j]), "lr_stat": float(lr),
        "delta_bic": float(n * np.log(max(total[j], 1e-300) / max(sse0, 1e-300)) + np.log(n)),
        "heldout_sse": cv, "heldout_improvement": float((sse0 - cv) / sse0) if sse0 > 0 else 0.0,
        "theta_fold": theta_fold, "_heldout_obj": held, "_fit": fits[at], "_theta_grid": float(grid[at]),
    }  # fmt: skip


def decide(ranking: list[dict], alias: dict, n_candidates: int, opts: DiagnosisConfig, noise: dict,
           exclude: tuple[str, ...] = ()) -> dict:  # fmt: skip
    """The verdict from per-effect results (also used by the benchmark to drop the true effect)."""
    crit = float(stats.chi2.ppf(1 - opts.alpha / max(n_candidates, 1), 1))
    tau = opts.model_floor or 0.0
    ok = [
        r for r in ranking
        if r["effect"] not in exclude and alias["effects"][r["effect"]]["identifiable"]
        and r["lr_stat"] > crit and r["heldout_improvement"] > 0 and r["explained_rms"] > tau
    ]  # fmt: skip
    ok.sort(key=lambda r: (-r["heldout_improvement"], r["effect"]))
    if not ok:
        return {"verdict": NONE, "class": None, "effect": None, "reason": "no candidate improves beyond noise",
                "lr_critical": crit, "partial": None}  # fmt: skip
    top = ok[0]
    cls = alias["effects"][top["effect"]]["class"]
    share = top.get("share_closed")
    if share is not None and share < opts.min_share:
        return {"verdict": NONE, "class": None, "effect": None, "lr_critical": crit,
                "reason": f"best candidate ({cls}) closes only {share:.0%} of the gap above the noise floor",
                "partial": cls}  # fmt: skip
    return {"verdict": cls, "class": cls, "effect": top["effect"], "reason": "improves beyond noise",
            "lr_critical": crit, "partial": None}  # fmt: skip


def diagnose(prob: Problem, effects: list[Effect], opts: DiagnosisConfig) -> Diagnosis:
    """Run every step on a prepared :class:`Problem`."""
    noise = _noise(prob, opts)
    sd = noise["sd"]
    sigma2 = sd**2 if sd else None
    fit0 = prob.initial_fit()
    pred0 = prob.predict(None, 0.0, fit0)
    resid0 = prob.y - pred0
    n, N = prob.obj.size, prob.n_obj
    where = localise(prob, fit0, resid0, sd, opts.alpha)
    alias = aliasing(prob, effects, fit0, opts)
    folds = _folds(N, opts.folds)

    def lack_of_fit(sse_total: float, n_params: int) -> float | None:
        df_pe = noise["pure_error_df"]
        if df_pe < 2 or noise["pure_error_ss"] <= 0:
            return None
        df_lof = noise["groups"] - n_params
        if df_lof < 1:
            return None
        f = ((sse_total - noise["pure_error_ss"]) / df_lof) / (noise["pure_error_ss"] / df_pe)
        return float(stats.f.sf(f, df_lof, df_pe))

    k = prob.k_free
    floor = sd * np.sqrt(max(n - k * N, 0) / n) if sd else None
    rms0 = float(np.sqrt(fit0.sse.sum() / n))
    ranking = []
    for e in effects:
        r = evaluate_effect(prob, e, fit0, opts, sigma2, fit0.sse, folds)
        r["class"] = alias["effects"][e.name]["class"]
        r["identifiable"] = alias["effects"][e.name]["identifiable"]
        r["lack_of_fit_p"] = lack_of_fit(r["sse"], k * N + 1)
        r["explained_rms"] = float(np.sqrt(max(fit0.sse.sum() - r["sse"], 0.0) / n))
        # share of the held-out RMS gap above the noise floor that the effect closes
        # (the same quantity as the shrinkage reported for the top effect)
        rms_h = float(np.sqrt(r["heldout_sse"] / n))
        r["share_closed"] = (
            float((rms0 - rms_h) / (rms0 - floor)) if floor is not None and rms0 - floor > 1e-12 else None
        )
        ranking.append(r)
        log.info("%-16s magnitude %+.4g [%+.4g, %+.4g]  LR %.1f  held-out %+.3f", e.name, r["magnitude"],
                 *r["ci95"], r["lr_stat"], r["heldout_improvement"])  # fmt: skip
    ranking.sort(key=lambda r: (-r["heldout_improvement"], r["effect"]))
    verdict = decide(ranking, alias, len(effects), opts, noise)

    # how far: held-out gap before/after the top effect (or the best partial one)
    name = verdict["effect"] or (ranking[0]["effect"] if verdict["partial"] else None)
    shrink: dict = {"effect": name, "before_rms": rms0, "noise_floor_rms": floor}
    anch0 = np.sqrt(fit0.sse / prob.counts)
    shrink["anchored_before_mean"] = float(anch0.mean())
    shrink["anchored_floor"] = (
        float(np.mean(sd * np.sqrt(np.maximum(prob.counts - k, 0) / prob.counts))) if sd else None
    )
    after_pred = None
    if name:
        top = next(r for r in ranking if r["effect"] == name)
        held = top["_heldout_obj"]
        rms1 = float(np.sqrt(held.sum() / n))
        anch1 = np.sqrt(held / prob.counts)
        shrink.update(after_rms=rms1, anchored_after_mean=float(anch1.mean()))
        eff = next(e for e in effects if e.name == name)
        after_pred = prob.predict(eff, top["_theta_grid"], top["_fit"])
    else:
        shrink.update(after_rms=rms0, anchored_after_mean=float(anch0.mean()))
    for pre, key0, key1, fl in (("gap", "before_rms", "after_rms", floor),
                                ("anchored", "anchored_before_mean", "anchored_after_mean", shrink["anchored_floor"])):  # fmt: skip
        b, a = shrink[key0], shrink[key1]
        share = (b - a) / (b - fl) if fl is not None and b - fl > 1e-12 else None
        shrink[f"{pre}_share_closed"] = share
    shrink["unexplained_rms_above_floor"] = (
        float(np.sqrt(max(shrink["after_rms"] ** 2 - floor**2, 0.0))) if floor is not None else shrink["after_rms"]
    )

    public_rank = [{k: v for k, v in r.items() if not k.startswith("_")} for r in ranking]
    summary = {
        "pushlog": prob.log.path,
        "n_pushes": int(n), "n_objects": int(N), "has_direction": prob.log.has_direction,
        "measured": {"mass": prob.fixed_lm is not None, "friction": prob.fixed_lu is not None},
        "noise": {k: v for k, v in noise.items() if k != "group"},
        "baseline": {"rms": rms0, "sse": float(fit0.sse.sum())},
        "localisation": where,
        "aliasing": alias,
        "ranking": public_rank,
        "verdict": verdict,
        "shrinkage": shrink,
        "options": opts.to_dict(),
        # the floor's parts: interpolation, and the simulator's error measured when the table was built
        "model_floor": prob.etables.meta.get("model_floor") if prob.etables is not None else None,
    }  # fmt: skip
    resid = {"speed": prob.v, "direction": prob.phi, "log_d": prob.y, "resid_before": resid0,
             "resid_after": None if after_pred is None else prob.y - after_pred}  # fmt: skip
    return Diagnosis(summary=summary, residuals=resid)
