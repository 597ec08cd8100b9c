"""Step 5 of the diagnosis: how far the accepted effects close the gap, held out.

The held-out RMS gap in log displacement before (the baseline fit) and after the
accepted effects (each object's parameters refitted at the effects fitted without its
fold), the share of the gap above the noise floor it closes (the floor holds a reference
session's noise where its readings are the baseline), and the same for stop
times, for both observables whitened together (what the verdict is judged on), and for
the objects' anchored disagreement. The lack of fit of the accepted model, held out, is
a chi-square at the noise and the model's own error; its overdispersion widens the
effects' intervals (``dispersion``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from imply.diagnose.inference.fit import JointFit, Problem
from imply.diagnose.inference.screening import folds
from imply.diagnose.inputs.pushlog import TRACK_OBSERVABLES
from imply.diagnose.records import Record, json_field
from imply.diagnose.tails import chi2_sf


@dataclass(frozen=True)
class HeldOut:
    """Each push's residuals at the effects fitted without its object's fold, and the objects refitted there."""

    resid_d: np.ndarray
    resid_t: np.ndarray | None
    lm: np.ndarray
    lu: np.ndarray


@dataclass(frozen=True, kw_only=True)
class ObservableFit(Record):
    """One observable's whitened sum of squares, baseline and held out, over its ``n`` kept pushes."""

    baseline_chi2: float
    heldout_chi2: float
    n: int


@dataclass(frozen=True, kw_only=True)
class LackOfFit(Record):
    """The accepted model's held-out chi-square (every observable, whitened by noise and model error)."""

    heldout_chi2: float
    dof: int
    p_value: float
    in_sample_chi2: float
    baseline_chi2: float
    displacement: ObservableFit
    stop_time: ObservableFit | None = json_field(omit_none=True, default=None)
    pusher_speed: ObservableFit | None = json_field(omit_none=True, default=None)
    track: dict[str, ObservableFit] | None = json_field(omit_none=True, default=None)  # by crossing-time observable


@dataclass(frozen=True, kw_only=True)
class Shrinkage(Record):
    """The gap before and after the accepted effects (or the best combination tried), held out."""

    effects: list[str]  # the model's effects: those the verdict accepts, or the partial best combination
    effect: str | None  # the same, joined by "+"
    before_rms: float
    after_rms: float
    noise_floor_rms: float | None
    gap_share_closed: float | None
    stop_time_share_closed: float | None
    both_share_closed: float | None
    lack_of_fit: LackOfFit
    dispersion: float
    anchored_before_mean: float
    anchored_after_mean: float
    anchored_floor: float
    anchored_share_closed: float | None
    unexplained_rms_above_floor: float

    @property
    def judged(self) -> float | None:
        """The share the verdict is judged on: both observables whitened, else displacement."""
        return self.both_share_closed if self.both_share_closed is not None else self.gap_share_closed


def heldout(problem: Problem, jf: JointFit, n_folds: int) -> HeldOut:
    """Each object's residuals at the effects fitted without its fold (objects refitted there)."""
    fold_of = folds(problem.n_obj, n_folds)
    model = jf.model
    if model.dim == 0:
        lm, lu = jf.objects.lm, jf.objects.lu
        th_obj = np.zeros((problem.n_obj, 0))
    else:
        per_fold = jf.leave_out(fold_of)
        keys = sorted(per_fold)
        thetas = np.stack([per_fold[k] for k in keys])
        lms, lus, _ = problem.refine_many(model, thetas, jf.objects.lm[None, :], jf.objects.lu[None, :], iters=6)
        which = np.searchsorted(keys, fold_of)
        lm = lms[which, np.arange(problem.n_obj)]
        lu = lus[which, np.arange(problem.n_obj)]
        th_obj = thetas[which]
    th_c = th_obj[problem.c_obj] if model.dim else np.zeros(0)
    rd, rt = problem.row_residuals(problem.predict(model, th_c, lm[problem.c_obj], lu[problem.c_obj]))
    return HeldOut(rd, rt, lm, lu)


def rms(x: np.ndarray, w: np.ndarray) -> float:
    """RMS of ``x`` over the rows weighted above 0."""
    keep = w > 0
    return float(np.sqrt(np.mean(x[keep] ** 2))) if keep.any() else float("nan")


def share_closed(before: float, after: float, floor: float | None) -> float | None:
    """The share of the gap above ``floor`` closed going from ``before`` to ``after`` (None: no gap)."""
    if floor is None or not np.isfinite(before) or before - floor <= 1e-12:
        return None
    return float((before - after) / (before - floor))


def shrinkage(
    problem: Problem, final: JointFit, *, resid_d: np.ndarray, resid_t: np.ndarray | None, held: HeldOut
) -> Shrinkage:
    """The gap closed by ``final``'s effects: baseline residuals ``resid_d`` / ``resid_t`` against the held-out ones."""
    rd0, rt0 = resid_d, resid_t
    n, N, k = problem.n_rows, problem.n_obj, problem.k_free
    # the noise a push's residual carries: the log's, and a reference session's where its reading is the baseline
    keep_d = problem.w_d > 0
    sd = problem.noise_d
    if problem.baseline_sd_d[keep_d].any():
        sd = float(np.sqrt(sd**2 + np.mean(problem.baseline_sd_d[keep_d] ** 2)))
    floor = sd * np.sqrt(max(n - k * N, 0) / n) if n else None
    rms0 = rms(rd0, problem.w_d)
    rms1 = rms(held.resid_d, problem.w_d)
    gap_share = share_closed(rms0, rms1, floor)
    use_t = problem.use_t
    # both observables, whitened: what the verdict's adequacy is judged on
    ro_w = np.concatenate([problem.w_d, problem.w_t]) if use_t else problem.w_d
    rw0 = np.concatenate([rd0 / problem.sd_d, rt0 / problem.sd_t]) if use_t else rd0 / problem.sd_d
    rw1 = (
        np.concatenate([held.resid_d / problem.sd_d, held.resid_t / problem.sd_t])
        if use_t
        else held.resid_d / problem.sd_d
    )
    nw = int((ro_w > 0).sum())
    # whitened by noise and model error together: an adequate model leaves unit variance
    # a freed launch is one more parameter per condition, fitted on the same rows (imply.diagnose.inference.launch)
    nuisance = problem.n_nuisance
    floor_w = float(np.sqrt(max(nw - k * N * (1 + len(problem.aux)) - nuisance, 0) / nw)) if nw else None
    both_share = share_closed(rms(rw0, ro_w), rms(rw1, ro_w), floor_w)
    stop_share = None
    stop_rows = problem.aux_rows("stop_time")
    if stop_rows.size:
        sd_t = problem.noise_t_rows[stop_rows[0]]
        if problem.baseline_sd_t[stop_rows].any():
            sd_t = float(np.sqrt(sd_t**2 + np.mean(problem.baseline_sd_t[stop_rows] ** 2)))
        floor_t = sd_t * np.sqrt(max(n - k * N, 0) / n)
        w_s = problem.w_t[stop_rows]
        stop_share = share_closed(rms(rt0[stop_rows], w_s), rms(held.resid_t[stop_rows], w_s), floor_t)

    # lack of fit of the accepted model, held out: at the noise and the model's own error an
    # adequate model leaves a chi-square; overdispersion also widens the effects' intervals
    keep_w = ro_w > 0
    lof_ss = float(np.sum((rw1[keep_w]) ** 2))
    lof_dof = max(nw - k * N - nuisance - final.model.dim, 1)

    def observable(r0: np.ndarray, r1: np.ndarray, w: np.ndarray) -> ObservableFit:
        kk = w > 0
        return ObservableFit(
            baseline_chi2=float(np.sum(r0[kk] ** 2)), heldout_chi2=float(np.sum(r1[kk] ** 2)), n=int(kk.sum())
        )

    aux_fits = {}
    for name in problem.aux:
        rows = problem.aux_rows(name)
        aux_fits[name] = observable((rt0 / problem.sd_t)[rows], (held.resid_t / problem.sd_t)[rows], problem.w_t[rows])
    lof = LackOfFit(
        heldout_chi2=lof_ss,
        dof=lof_dof,
        p_value=chi2_sf(float(lof_ss), float(lof_dof)),
        in_sample_chi2=final.sse,
        baseline_chi2=float(np.sum(rw0[keep_w] ** 2)),
        displacement=observable(rd0 / problem.sd_d, held.resid_d / problem.sd_d, problem.w_d),
        **{k: f for k, f in aux_fits.items() if k not in TRACK_OBSERVABLES},
        track={k: f for k, f in aux_fits.items() if k in TRACK_OBSERVABLES} or None,
    )
    dispersion = max(final.sse / lof_dof, 1.0)
    unexplained = float(np.sqrt(max(rms1**2 - floor**2, 0.0))) if floor is not None else rms1
    anch0 = np.sqrt(np.bincount(problem.obj, (problem.w_d * rd0) ** 2, minlength=N) / np.maximum(problem.counts, 1))
    anch1 = np.sqrt(
        np.bincount(problem.obj, (problem.w_d * held.resid_d) ** 2, minlength=N) / np.maximum(problem.counts, 1)
    )
    anch_floor = float(np.mean(sd * np.sqrt(np.maximum(problem.counts - k, 0) / np.maximum(problem.counts, 1))))
    return Shrinkage(
        effects=final.model.names,
        effect="+".join(final.model.names) or None,
        before_rms=rms0,
        after_rms=rms1,
        noise_floor_rms=floor,
        gap_share_closed=gap_share,
        stop_time_share_closed=stop_share,
        both_share_closed=both_share,
        lack_of_fit=lof,
        dispersion=dispersion,
        anchored_before_mean=float(anch0.mean()),
        anchored_after_mean=float(anch1.mean()),
        anchored_floor=anch_floor,
        anchored_share_closed=share_closed(float(anch0.mean()), float(anch1.mean()), anch_floor),
        unexplained_rms_above_floor=unexplained,
    )
