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
  as well be ...") and not stated as a cause;
- **alternatives**: at the step where an effect was accepted, every other candidate whose
  held-out gain came within ``alt_margin`` of it fits about as well, and is named beside
  it with the measurement that would tell them apart;
- **outside the library**: an effect that the data pull past its library bound (the
  profiled sum of squares would fall by more than the 95% chi-square quantile of one
  degree of freedom beyond it), or three or more terms at once (library effects, the
  discrepancy counted as one), are no
  confident verdict: the combination describes the residual, and the likely cause is a
  mechanism the library does not have.

``alt_margin`` is a difference of held-out chi-squares (twice a log likelihood ratio);
its default 6 is the customary threshold of "strong" evidence, fixed before the
benchmark was run, not tuned on it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import stats

from imply.diagnose.candidates import CANDIDATES, DISCREPANCY, SPEED_GAIN, SPEED_OFFSET, TILT
from imply.diagnose.fit import JointFit, Problem
from imply.diagnose.records import Record, json_field
from imply.diagnose.selection import Selection, folds

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


def _cv(problem: Problem, jf: JointFit, fold_of: np.ndarray) -> float:
    return float(jf.heldout_sse_quadratic(fold_of).sum())


def _drop_mimicked(problem: Problem, fit: JointFit, fold_of: np.ndarray, margin: float):
    """Library effects the discrepancy explains as well, dropped one at a time (cheapest first)."""
    dropped: dict[str, float] = {}
    while fit.model.discrepancy is not None and fit.model.library:
        base = _cv(problem, fit, fold_of)
        trials = []
        for c in fit.model.library:
            jf = problem.fit(fit.model.without(c.name), fit.model.theta_without(fit.theta, c.name), fit.objects)
            trials.append((_cv(problem, jf, fold_of) - base, c.name, jf))
        cost, name, jf = min(trials, key=lambda t: (t[0], t[1]))
        if cost >= margin:
            break
        dropped[name] = float(cost)
        fit = jf
    return fit, dropped


def _pinned(fit: JointFit, level: float = 0.95) -> list[Pinned]:
    """Library effects at their bound that the data pull beyond it (one-step profiled drop of the sum of squares)."""
    crit = float(stats.chi2.ppf(level, 1))
    return [Pinned(effect=k, drop_beyond_bound=v, critical=crit) for k, v in fit.pulled_past_bounds(level).items()]


def explain(
    problem: Problem, selection: Selection, *, n_folds: int, alt_margin: float, mimics: list[str] = ()
) -> tuple[Explanations, JointFit]:
    """What the verdict may state of the accepted terms, and the final fit (mimicked effects left out).

    ``mimics``: the library effects the discrepancy can imitate on this log's design
    (:attr:`imply.diagnose.aliasing.Aliasing.mimicked`). One of them kept beside the discrepancy is
    confounded with it: how much of the gap goes to either is set by the discrepancy's prior, not by
    the pushes, so it is named beside the discrepancy and not stated as a cause."""
    fold_of = folds(problem.n_obj, n_folds)
    fit, dropped = _drop_mimicked(problem, selection.fit, fold_of, alt_margin)
    confounded = [c.name for c in fit.model.library if c.name in mimics] if fit.model.discrepancy is not None else []
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
    reason = None
    if pinned:
        reason = (f"{' and '.join(CANDIDATES[p.effect].phrase for p in pinned)} would go past the library's largest "
                  "magnitude: "
                  "most likely a mechanism outside the library")  # fmt: skip
    elif len(fit.model.candidates) >= 3:  # the discrepancy counts as one term: it is one more thing to explain
        reason = (f"{len(causes)} library effects at once"
                  + (" beside a smooth discrepancy" if fit.model.discrepancy is not None else "")
                  + ": most likely a mechanism outside the library")  # fmt: skip
    return (
        Explanations(
            causes=causes, discrepancy=fit.model.discrepancy is not None, confounded=confounded, mimicked=list(dropped),
            mimicked_margin=dropped, alternatives=alternatives, pinned=pinned, outside_library=reason is not None,
            reason=reason, alt_margin=alt_margin,
        ),
        fit,
    )  # fmt: skip


def separators(names: list[str]) -> list[str]:
    """The measurements that would tell the named terms apart (each said once, in the order of ``names``)."""
    out = []
    for n in names:
        how = SEPARATE_BY.get(n)
        if how and how not in out:
            out.append(how)
    return out
