"""Each candidate on its own, fitted on top of the baseline: the screening pass of the hypotheses and the
report's ranking.

:func:`fit_candidate` adds a candidate to a fitted model and refits jointly (all the
model's parameters and every object's mass and friction;
:meth:`imply.diagnose.inference.fit.Problem.fit`, started from the best point of a scan of the new
candidate's range); :mod:`imply.diagnose.inference.hypotheses` grows every hypothesis with it.
:func:`screened` says, for the ranking, what a candidate fitted alone does: its
likelihood-ratio statistic against the chi-square quantile at ``alpha`` / (candidates
tried) for its number of components, the leave-one-object-out (``folds``) held-out sum
of squares it removes, and whether it explains more than the model's own accuracy (its
explained mean square per push against the model's own error's,
:mod:`imply.diagnose.inference.model_error`). These tests describe; the hypotheses' weights decide.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from imply.diagnose.inference.fit import JointFit, ObjectFit, Problem
from imply.diagnose.physics.candidates import Candidate
from imply.diagnose.tails import chi2_ppf

log = logging.getLogger("imply.diagnose")


@dataclass(frozen=True)
class StepResult:
    """One candidate fitted alone: its joint fit and the ranking's three tests."""

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


def folds(n_obj: int, k: int) -> np.ndarray:
    """Each object's fold: leave one object out (``k`` 0), or ``k`` folds."""
    if k <= 0 or k >= n_obj:
        return np.arange(n_obj)
    return np.arange(n_obj) % max(2, k)


def _scan_points(c: Candidate, n: int) -> np.ndarray:
    """Starting values of a candidate's components across its range (the origin excluded)."""
    if c.prior_sd is not None:  # the discrepancy is linear in its coefficients: start at none
        return np.zeros((1, c.dim))
    if c.dim == 1:
        lo, hi = c.lo[0], c.hi[0]
        pts = np.linspace(lo, hi, n)
        pts = pts[np.abs(pts) > 1e-12 * max(abs(lo), abs(hi))]
        return pts[:, None]
    r = c.radius
    az = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    out = [np.stack([f * r * np.cos(az), f * r * np.sin(az)], 1) for f in (0.25, 0.6, 1.0)]
    return np.concatenate(out)


def fit_candidate(problem: Problem, base: JointFit, c: Candidate, *, scan: int) -> JointFit:
    """``base``'s model plus ``c``, fitted jointly, started from the best of ``scan`` points of c's range."""
    model = base.model.plus(c)
    pts = _scan_points(c, scan)
    thetas = np.concatenate([np.repeat(base.theta[None, :], len(pts), 0), pts], 1)
    thetas = np.stack([model.project(t) for t in thetas])
    _, _, sse = problem.refine_many(model, thetas, base.objects.lm[None, :], base.objects.lu[None, :], iters=3)
    total = sse.sum(1)
    best = thetas[int(np.argmin(total))]
    start_obj = ObjectFit(base.objects.lm, base.objects.lu, base.objects.sse)
    return problem.fit(model, best, start_obj)


def model_error_ms(problem: Problem) -> float:
    """The model's own error as a mean square per push, in whitened units (both observables)."""
    keep = problem.w_d > 0
    md = np.broadcast_to(problem.model_err_d / problem.sd_d, problem.y.shape)[keep]
    out = float(np.mean(md**2)) if keep.any() else 0.0
    if problem.use_t:
        keep_t = problem.w_t > 0
        mt = np.broadcast_to(problem.model_err_t / problem.sd_t, problem.t_row.shape)[keep_t]
        out += float(np.mean(mt**2)) if keep_t.any() else 0.0
    return out


def screened(
    problem: Problem, base: JointFit, singles: list[JointFit], *, alpha: float, fold_of: np.ndarray
) -> list[StepResult]:
    """Each candidate fitted alone on top of ``base`` (``singles``, the candidate last in each model), described by
    the ranking's three tests, largest held-out gain first."""
    n = max(problem.n_rows, 1)
    floor_ms = model_error_ms(problem)
    cv0 = float(base.heldout_sse_quadratic(fold_of).sum())
    out = []
    for jf in singles:
        c = jf.model.candidates[-1]
        lr = max(base.sse - jf.sse, 0.0)
        crit = chi2_ppf(1 - alpha / max(len(singles), 1), c.dim)
        gain = float(cv0 - jf.heldout_sse_quadratic(fold_of).sum())
        explained = lr / n
        reasons = []
        if lr <= crit:
            reasons.append(f"likelihood ratio {lr:.1f} <= {crit:.1f}")
        if gain <= 0:
            reasons.append("does not lower the held-out sum of squares")
        if explained <= floor_ms:
            reasons.append("explains less than the model's own accuracy")
        out.append(
            StepResult(
                c, jf, lr, c.dim, crit, gain, gain / cv0 if cv0 > 0 else 0.0, explained, floor_ms, not reasons, reasons
            )
        )
    return sorted(out, key=lambda r: (-r.heldout_gain, r.candidate.name))
