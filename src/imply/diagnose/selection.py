"""Step 4 of the diagnosis: forward selection of the candidate effects that explain the gap.

Starting from the baseline, every identifiable candidate not yet in the model (nor in
the alias class of one that is) is added in turn and the model is refitted jointly (all
its effects' parameters and every object's mass and friction;
:meth:`imply.diagnose.fit.Problem.fit`, started from the best point of a scan of the new
candidate's range). A candidate qualifies when (a) its likelihood-ratio statistic beats
the chi-square quantile at ``alpha`` / (candidates left) for its number of components,
(b) it lowers the leave-one-object-out (``folds``) held-out sum of squares, and (c) it
explains more than the model's own accuracy (its explained mean square per push is above
the model's own error's, :mod:`imply.diagnose.model_error`). The qualifying candidate
that lowers the held-out sum of squares most is accepted, the model's own error is
counted anew with it, and the search goes on (at most ``max_effects``).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
from scipy import stats

from imply.diagnose.aliasing import Aliasing
from imply.diagnose.candidates import Candidate
from imply.diagnose.fit import JointFit, ObjectFit, Problem
from imply.diagnose.model_error import model_error
from imply.options import Config

log = logging.getLogger("imply.diagnose")


@dataclass(frozen=True)
class StepResult:
    """One candidate tried at one step: its joint fit and the three tests it must pass."""

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


@dataclass(frozen=True)
class Selection:
    """The accepted effects' final fit, every step's results (best first), and the problem it was fitted
    under (its model error is the accepted effects')."""

    fit: JointFit
    steps: list[list[StepResult]]
    accepted: list[Candidate]
    problem: Problem


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
        mt = np.broadcast_to(problem.model_err_t / problem.sd_t, problem.y.shape)[keep_t]
        out += float(np.mean(mt**2)) if keep_t.any() else 0.0
    return out


def _try(problem: Problem, current: JointFit, c: Candidate, *, n_left: int, cv0: float, floor_ms: float,
         fold_of: np.ndarray, opts: Config) -> StepResult:  # fmt: skip
    """Candidate ``c`` added to ``current``: fitted, and tested against the three criteria."""
    n = max(problem.n_rows, 1)
    jf = fit_candidate(problem, current, c, scan=opts.scan)
    lr = max(current.sse - jf.sse, 0.0)
    crit = float(stats.chi2.ppf(1 - opts.alpha / n_left, c.dim))
    cv1 = jf.heldout_sse_quadratic(fold_of).sum()
    gain = float(cv0 - cv1)
    explained = lr / n
    reasons = []
    if lr <= crit:
        reasons.append(f"likelihood ratio {lr:.1f} <= {crit:.1f}")
    if gain <= 0:
        reasons.append("does not lower the held-out sum of squares")
    if explained <= floor_ms:
        reasons.append("explains less than the model's own accuracy")
    log.debug("%-16s LR %.1f (crit %.1f) held-out -%.1f explained %.3g (floor %.3g)", c.name, lr, crit, gain,
              explained, floor_ms)  # fmt: skip
    return StepResult(c, jf, lr, c.dim, crit, gain, gain / cv0 if cv0 > 0 else 0.0, explained, floor_ms, not reasons,
                      reasons)  # fmt: skip


def _prefer_mechanism(problem: Problem, ok: list[StepResult], tried: list[StepResult], *, cv0: float,
                      fold_of: np.ndarray, opts: Config) -> StepResult:  # fmt: skip
    """The qualifying candidate to accept (``ok`` sorted best first): the best library effect, unless the
    model discrepancy lowers the held-out sum of squares by more than ``alt_margin`` beyond it and beyond
    the best pair of library effects (one of the three best qualifying ones, and any other ``tried``). A
    mechanism is said when one
    or two of them explain about as well as a generic smooth function; the function when it explains
    clearly better."""
    margin = opts.alt_margin
    library = [r for r in ok if r.candidate.is_library]
    if not library or ok[0].candidate.is_library:
        return ok[0]
    disc = ok[0]
    if disc.heldout_gain - library[0].heldout_gain <= margin:
        return library[0]
    best, best_gain = disc, disc.heldout_gain - margin
    for first in library[:3]:
        for second in tried:
            if second.candidate is first.candidate or not second.candidate.is_library:
                continue
            pair = fit_candidate(problem, first.fit, second.candidate, scan=opts.scan)
            gain = cv0 - pair.heldout_sse_quadratic(fold_of).sum()
            if gain >= best_gain:
                best, best_gain = first, gain
    return best


def forward_select(
    problem: Problem, base: JointFit, candidates: list[Candidate], *, alias: Aliasing, opts: Config
) -> Selection:
    """Add candidates while each still qualifies (``opts``: ``folds``, ``alpha``, ``scan``, ``max_effects``
    and the model floors)."""
    fold_of = folds(problem.n_obj, opts.folds)
    current = base
    accepted: list[Candidate] = []
    steps: list[list[StepResult]] = []
    pool = [c for c in candidates if alias.effects[c.name].identifiable]
    for _ in range(max(opts.max_effects, 0)):
        taken = {alias.effects[a.name].cls for a in accepted}
        left = [c for c in pool if c not in accepted and alias.effects[c.name].cls not in taken]
        if not left:
            break
        floor_ms = model_error_ms(problem)
        cv0 = current.heldout_sse_quadratic(fold_of).sum()
        results = [_try(problem, current, c, n_left=len(left), cv0=cv0, floor_ms=floor_ms, fold_of=fold_of,
                        opts=opts) for c in left]  # fmt: skip
        results.sort(key=lambda r: (-r.heldout_gain, r.candidate.name))
        steps.append(results)
        ok = [r for r in results if r.qualifies]
        if not ok:
            break
        choice = _prefer_mechanism(problem, ok, results, cv0=cv0, fold_of=fold_of, opts=opts)
        accepted.append(choice.candidate)
        current = choice.fit
        # the accepted effects' own tables are only so accurate: count it, and refit under it (the
        # objects searched globally again: an accepted effect can move their optimum far)
        problem = model_error(problem, current.model, current.theta, objects=current.objects, opts=opts).apply(problem)
        current = problem.fit(
            current.model, current.theta, problem.initial_fit(current.model, current.theta, n_grid=31)
        )
    return Selection(current, steps, accepted, problem)
