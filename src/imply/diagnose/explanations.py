"""Step 5 of the diagnosis: which of the accepted terms the verdict may state as causes, and what else fits as well.

Forward selection (:mod:`~imply.diagnose.selection`) may accept library effects and the
model discrepancy (:func:`imply.diagnose.candidates.discrepancy_candidate`) side by side.
This step decides what the verdict can say of them:

- **mimicked by the discrepancy**: a library effect whose removal from a model that holds
  the discrepancy costs less than ``alt_margin`` in held-out chi-square (the discrepancy
  refitted without it explains the pushes about as well) is not a cause; it is named as
  an alternative to the discrepancy;
- **confounded with the discrepancy**: a library effect kept beside the discrepancy that
  the discrepancy can imitate on this log's design is named beside it ("part of it could
  as well be ...") and not stated as a cause, unless the pushes themselves prefer it: at
  the step it was accepted it lowered the held-out chi-square by more than ``alt_margin``
  beyond the discrepancy tried at the same step;
- **alternatives**: at the step where an effect was accepted, every other candidate whose
  held-out gain came within ``alt_margin`` of it fits about as well, and is named beside
  it with the measurement that would tell them apart;
- **fingerprinted**: a library effect of the final model whose change depends on the push
  direction (a tilt, an anisotropy), which no smooth discrepancy in speed, mass and
  friction can make, is stated as a cause whatever the rest of the gap does (even when
  the other terms are flagged as outside the library, or together close too little:
  :func:`imply.diagnose.verdict.judge`) if on this log's design at least half of its
  projected change, in sum of squares, lies outside the discrepancy's reach (a squared
  canonical correlation ``FINGERPRINT_R2`` or less), it is not at its bound, its removal
  from the final model costs, held out, at least ``alt_margin`` and the selection's own
  critical value (the chi-square quantile at ``alpha`` over the candidates tried), in
  units of the final model's held-out chi-square per row where that is above 1 (a gap
  left open inflates every difference of chi-squares), and it leaves no direction
  dependence behind: the final model's residuals, averaged over replicates, show none
  (an F test at ``alpha`` of cos/sin of the direction and twice it, each times 1, speed,
  mass and friction, beside one mean per object; on log d and on log stop time where the
  log has stop times, Bonferroni). Direction dependence left over means
  that something else shaped by direction is at work (friction that varies along the
  table looks like a tilt, but not quite), so nothing is stated on the strength of it;
- **outside the library**: an effect that the data pull past its library bound (the
  profiled sum of squares would fall by more than the 95% chi-square quantile of one
  degree of freedom beyond it), or three or more terms at once (library effects, the
  discrepancy counted as one), are no confident verdict: the combination describes the
  residual, and the likely cause is a mechanism the library does not have. Fingerprinted
  effects stay causes beside it.

``alt_margin`` is a difference of held-out chi-squares (twice a log likelihood ratio);
its default 6 is the customary threshold of "strong" evidence, fixed before the
benchmark was run, not tuned on it. ``FINGERPRINT_R2`` (one half: more of the effect's
signal is beyond the discrepancy's reach than within it) was fixed before any benchmark
run too.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from imply.diagnose.candidates import (
    CANDIDATES,
    DISCREPANCY,
    FRICTION2,
    SPEED_GAIN,
    SPEED_OFFSET,
    TILT,
    Candidate,
    Model,
    scaled,
)
from imply.diagnose.fit import JointFit, Problem
from imply.diagnose.records import Record, json_field
from imply.diagnose.selection import Selection, folds

# a library effect is fingerprinted when at most this share of its projected change (squared canonical
# correlation) is something the discrepancy can imitate on the log's design
FINGERPRINT_R2 = 0.5
DIRECTIONAL = (TILT, FRICTION2)  # candidate kinds whose change depends on the push direction

# what would tell an effect from another that fits as well (by candidate; "discrepancy" for the model discrepancy)
SEPARATE_BY = {
    SPEED_GAIN: "measure the pusher's actual speed",
    SPEED_OFFSET: "measure the pusher's actual speed, and add pushes below and above this speed range",
    "viscous": "add pushes of heavy and light objects at the same speeds (viscous drag acts less on heavy ones)",
    "air_drag": "add pushes above this speed range (drag grows with the square of speed)",
    "pusher_softness": "record the pusher's contact force or the box's speed during the stroke",
    TILT: "push in more directions",
    "anisotropic": "push in more directions",
    "torsional": "record the box's rotation",
    "rolling": "record the box's rotation",
    "height": "measure the boxes' height",
    DISCREPANCY: "measure friction and the pusher's speed directly, and record stop times",
}


@dataclass(frozen=True, kw_only=True)
class Alternative(Record):
    """Explanations that fit about as well as a term of the verdict (held-out chi-square within the margin)."""

    effect: str
    instead: list[str]
    margin: list[float]  # held-out chi-square each alternative leaves above the term's (negative: below)
    separate_by: list[str]  # measurements that would tell them apart


@dataclass(frozen=True, kw_only=True)
class Pinned(Record):
    """A library effect the data pull past its bound: the drop of the sum of squares beyond it."""

    effect: str
    drop_beyond_bound: float
    critical: float


@dataclass(frozen=True, kw_only=True)
class Explanations(Record):
    """What the verdict may state: causes, effects the discrepancy mimics, alternatives, the outside-library flag."""

    causes: list[str]  # library effects of the final model stated as causes
    discrepancy: bool  # the final model holds the discrepancy
    # library effects kept in the fit beside the discrepancy that it can imitate on this design: part of the
    # discrepancy could as well be them, so they are named beside it, not stated as causes
    confounded: list[str] = json_field(default_factory=list)
    mimicked: list[str]  # library effects dropped because the discrepancy explains them as well
    mimicked_margin: dict[str, float]  # the held-out chi-square each one's removal cost
    alternatives: list[Alternative]
    pinned: list[Pinned]
    outside_library: bool
    reason: str | None  # why the verdict is not confident (None: it is)
    alt_margin: float
    # causes with a fingerprint no smooth discrepancy can make on this design, each significant in the final
    # model on its own: stated even where the rest of the gap is flagged or stays open
    fingerprinted: list[str] = json_field(default_factory=list)
    # what each one's removal costs, held out, in units of the final model's dispersion
    removal_cost: dict[str, float] = json_field(default_factory=dict)
    # p-value of the direction dependence the final model leaves in the residuals (None: not tested)
    direction_left_p: float | None = json_field(omit_none=True, default=None)


def _cv(problem: Problem, jf: JointFit, fold_of: np.ndarray) -> float:
    return float(jf.heldout_sse_quadratic(fold_of).sum())


def _refit_without(problem: Problem, fit: JointFit, name: str) -> JointFit:
    """``fit`` with the library effect ``name`` left out, the rest refitted from where they stood."""
    return problem.fit(fit.model.without(name), fit.model.theta_without(fit.theta, name), fit.objects)


def _drop_mimicked(problem: Problem, fit: JointFit, fold_of: np.ndarray, margin: float):
    """Library effects the discrepancy explains as well, dropped one at a time (cheapest first)."""
    dropped: dict[str, float] = {}
    while fit.model.discrepancy is not None and fit.model.library:
        base = _cv(problem, fit, fold_of)
        trials = []
        for c in fit.model.library:
            jf = _refit_without(problem, fit, c.name)
            trials.append((_cv(problem, jf, fold_of) - base, c.name, jf))
        cost, name, jf = min(trials, key=lambda t: (t[0], t[1]))
        if cost >= margin:
            break
        dropped[name] = float(cost)
        fit = jf
    return fit, dropped


def _removal_cost(problem: Problem, fit: JointFit, name: str, fold_of: np.ndarray) -> float:
    """The held-out chi-square that leaving library effect ``name`` out of ``fit`` (the rest refitted) costs."""
    return _cv(problem, _refit_without(problem, fit, name), fold_of) - _cv(problem, fit, fold_of)


def _direction_p(r: np.ndarray, phi: np.ndarray, obj: np.ndarray, n_obj: int, covariates: list[np.ndarray]) -> float:
    """p-value of an F test of cos/sin of ``phi`` and of twice it, each times 1 and each covariate, on ``r``
    beside one mean per object (1.0 where the directions cannot show any)."""
    objects = (obj[:, None] == np.arange(n_obj)[None, :]).astype(float)
    ways = np.stack([np.cos(phi), np.sin(phi), np.cos(2 * phi), np.sin(2 * phi)], 1)
    directional = np.concatenate([ways * x[:, None] for x in (np.ones_like(phi), *covariates)], 1)

    def rss_rank(x: np.ndarray) -> tuple[float, int]:
        coef, _, rank, _ = np.linalg.lstsq(x, r, rcond=1e-9)
        return float(np.sum((r - x @ coef) ** 2)), int(rank)

    rss0, p0 = rss_rank(objects)
    rss1, p1 = rss_rank(np.concatenate([objects, directional], 1))
    k, dof = p1 - p0, r.size - p1
    if k <= 0 or dof <= 0 or rss1 <= 0:
        return 1.0
    return float(stats.f.sf((rss0 - rss1) / k / (rss1 / dof), k, dof))


def direction_left(problem: Problem, fit: JointFit) -> float:
    """p-value of the direction dependence left in ``fit``'s residuals, replicates averaged: the smaller of the
    log d and log stop time tests (where stop times are used) times the number of tests, each an F test of cos/sin
    of the direction and of twice it, each times 1, speed, mass and friction (scaled), beside one mean per object."""
    lm_c, lu_c = fit.objects.lm[problem.c_obj], fit.objects.lu[problem.c_obj]
    observed = problem.row_residuals(problem.predict(fit.model, fit.theta, lm_c, lu_c))
    weights = (problem.w_d, problem.w_t)
    ps = []
    for resid, w in zip(observed, weights, strict=True):
        if resid is None:
            continue
        keep = w > 0
        n_c = np.bincount(problem.cond[keep], minlength=problem.n_cond)
        seen = n_c > 0
        r = np.bincount(problem.cond[keep], resid[keep], minlength=problem.n_cond)[seen] / n_c[seen]
        covariates = [scaled(problem.c_v[seen], *problem.v_range), scaled(lm_c[seen], *problem.lm_range),
                      scaled(lu_c[seen], *problem.lu_range)]  # fmt: skip
        ps.append(_direction_p(r, problem.c_phi[seen], problem.c_obj[seen], problem.n_obj, covariates))
    return min(1.0, min(ps) * len(ps))


def fingerprinted(
    problem: Problem, fit: JointFit, causes: list[Candidate], *, mimic_r: dict[str, float], pinned: set[str],
    fold_of: np.ndarray, margin: float, alpha: float = 0.05, n_tried: int = 1,
) -> dict[str, float]:  # fmt: skip
    """The ``causes`` whose change depends on the push direction, at most ``FINGERPRINT_R2`` of it (squared
    canonical correlation) within the discrepancy's reach on this design, not ``pinned`` at their bound, whose
    removal from ``fit`` costs, held out and in units of ``fit``'s own dispersion (its held-out chi-square per row,
    at least 1), at least ``margin`` and the selection's own critical value (the chi-square quantile at ``alpha`` /
    ``n_tried`` for the effect's components): {name: that scaled cost}."""
    out = {}
    dispersion = None
    for c in causes:
        if c.kind not in DIRECTIONAL or c.name in pinned or mimic_r.get(c.name, 1.0) ** 2 > FINGERPRINT_R2:
            continue
        if dispersion is None:  # the rest of the gap left open inflates every chi-square difference by this much
            dispersion = max(1.0, _cv(problem, fit, fold_of) / max(problem.n_rows, 1))
        cost = _removal_cost(problem, fit, c.name, fold_of) / dispersion
        if cost >= max(margin, float(stats.chi2.ppf(1 - alpha / max(n_tried, 1), c.dim))):
            out[c.name] = float(cost)
    return out


def preferred_to_discrepancy(selection: Selection, margin: float) -> set[str]:
    """The accepted library effects that, at the step they were accepted, lowered the held-out chi-square by more
    than ``margin`` beyond the discrepancy tried at the same step: the pushes prefer them, not the prior."""
    out = set()
    for acc, step in zip(selection.accepted, selection.steps, strict=False):
        chosen = next((r for r in step if r.candidate.name == acc.name), None)
        disc = next((r for r in step if not r.candidate.is_library), None)
        if acc.is_library and chosen is not None and disc is not None:
            if chosen.heldout_gain - disc.heldout_gain > margin:
                out.add(acc.name)
    return out


def _pinned(fit: JointFit, level: float = 0.95) -> list[Pinned]:
    """Library effects at their bound that the data pull beyond it (one-step profiled drop of the sum of squares)."""
    crit = float(stats.chi2.ppf(level, 1))
    return [Pinned(effect=k, drop_beyond_bound=v, critical=crit) for k, v in fit.pulled_past_bounds(level).items()]


def explain(
    problem: Problem, selection: Selection, *, n_folds: int, alt_margin: float, mimics: list[str] = (),
    mimic_r: dict[str, float] | None = None, alpha: float = 0.05,
) -> tuple[Explanations, JointFit]:  # fmt: skip
    """What the verdict may state of the accepted terms, and the final fit (mimicked effects left out).

    ``mimics``: the library effects the discrepancy can imitate on this log's design
    (:attr:`imply.diagnose.aliasing.Aliasing.mimicked`). One of them kept beside the discrepancy is
    confounded with it: how much of the gap goes to either is set by the discrepancy's prior, not by
    the pushes, so it is named beside the discrepancy and not stated as a cause. ``mimic_r``: each
    library effect's largest canonical correlation with the discrepancy on this design
    (:attr:`imply.diagnose.aliasing.Aliasing.discrepancy_mimics`; without it no effect is fingerprinted);
    ``alpha``: the level of the test for direction dependence left over."""
    fold_of = folds(problem.n_obj, n_folds)
    fit, dropped = _drop_mimicked(problem, selection.fit, fold_of, alt_margin)
    preferred = preferred_to_discrepancy(selection, alt_margin)
    confounded = ([c.name for c in fit.model.library if c.name in mimics and c.name not in preferred]
                  if fit.model.discrepancy is not None else [])  # fmt: skip
    alternatives = []
    # the discrepancy alone, against the whole final model (from the baseline's held-out sum of squares)
    first = selection.steps[0] if selection.steps else []
    disc_alone = next((r for r in first if not r.candidate.is_library), None)
    final_gain = None
    if first:
        cv0 = _cv(problem, first[0].fit, fold_of) + first[0].heldout_gain
        final_gain = cv0 - _cv(problem, fit, fold_of)
    for j, acc in enumerate(selection.accepted):
        step = selection.steps[j]
        chosen = next(r for r in step if r.candidate.name == acc.name)
        # one effect swapped for another at the step it was accepted
        rivals = [r for r in step if r.candidate.name != acc.name and r.candidate.is_library and r.heldout_gain > 0
                  and chosen.heldout_gain - r.heldout_gain < alt_margin]  # fmt: skip
        names = [r.candidate.name for r in rivals]
        gaps = [float(chosen.heldout_gain - r.heldout_gain) for r in rivals]
        if acc.name in dropped:  # mimicked: the discrepancy is its alternative, and it is the discrepancy's
            names, gaps = [DISCREPANCY, *names], [dropped[acc.name], *gaps]
        elif (j == 0 and acc.is_library and fit.model.discrepancy is None and disc_alone is not None
              and final_gain is not None and final_gain - disc_alone.heldout_gain < alt_margin):  # fmt: skip
            names, gaps = [DISCREPANCY, *names], [float(final_gain - disc_alone.heldout_gain), *gaps]
        if names:
            alternatives.append(Alternative(effect=acc.name, instead=names, margin=gaps,
                                            separate_by=separators([acc.name, *names])))  # fmt: skip
    pinned = _pinned(fit)
    causes = [c.name for c in fit.model.library if c.name not in confounded]
    marked = fingerprinted(problem, fit, [c for c in fit.model.library if c.name in causes], mimic_r=mimic_r or {},
                           pinned={p.effect for p in pinned}, fold_of=fold_of, margin=alt_margin, alpha=alpha,
                           n_tried=len(first))  # fmt: skip
    left = direction_left(problem, fit) if marked else None
    if left is not None and left < alpha:  # direction dependence left over: not this effect's fingerprint alone
        marked = {}
    reason = outside_reason(pinned, fit.model)
    return (
        Explanations(
            causes=causes, discrepancy=fit.model.discrepancy is not None, confounded=confounded, mimicked=list(dropped),
            mimicked_margin=dropped, alternatives=alternatives, pinned=pinned, outside_library=reason is not None,
            reason=reason, alt_margin=alt_margin, fingerprinted=list(marked), removal_cost=marked,
            direction_left_p=left,
        ),
        fit,
    )  # fmt: skip


def outside_reason(pinned: list[Pinned], model: Model) -> str | None:
    """Why the final ``model`` is no confident verdict (None: it is one): effects the data pull past their bound
    (``pinned``), or three or more terms at once (every library effect, confounded ones too, and the discrepancy
    as one)."""
    if pinned:
        return (f"{' and '.join(CANDIDATES[p.effect].phrase for p in pinned)} would go past the library's largest "
                "magnitude: most likely a mechanism outside the library")  # fmt: skip
    if len(model.candidates) >= 3:
        return (f"{len(model.library)} library effects at once"
                + (" beside a smooth discrepancy" if model.discrepancy is not None else "")
                + ": most likely a mechanism outside the library")  # fmt: skip
    return None


def separators(names: list[str]) -> list[str]:
    """The measurements that would tell the named terms apart (each said once, in the order of ``names``)."""
    out = []
    for n in names:
        how = SEPARATE_BY.get(n)
        if how and how not in out:
            out.append(how)
    return out
