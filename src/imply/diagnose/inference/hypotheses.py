"""Explanations of a push log, enumerated and weighed by one criterion.

A *hypothesis* is a set of library effects (at most ``max_effects``, at most one per alias
class) with or without the model discrepancy. Each one is fitted jointly with every
object's mass and friction (:meth:`imply.diagnose.inference.fit.Problem.fit`) under the same noise
and model error (the baseline's), so their sums of squares are comparable, and scored by
its Laplace-approximated log evidence:

    log Z = -chi2 / (2 c) - theta' P theta / 2 + log prior(theta) + (p / 2) log 2 pi - log det(A) / 2,
    A = H / c + P,

where chi2 is the whitened sum of squares at the fit, H its Gauss-Newton Hessian in theta
with the objects profiled out (each object's Schur complement, summed), P the
discrepancy's prior precision, the prior of a library effect uniform over its library
range (a disk for a tilt or an anisotropy), and c the dispersion: the smallest
chi2 per degree of freedom of any hypothesis, at least 1. Dividing by c is the
quasi-likelihood correction: where the contact is not the table's, no hypothesis fits
to the noise, and without it every difference of chi-squares would be read as
overwhelming evidence. The weights are the evidences normalised over the hypotheses.

Why the evidence and not the held-out chi-square: the Occam factor (prior volume against
posterior width) grows with the data, so on a log with nothing to find an effect that
fits a little noise does not take weight from the baseline (a held-out chi-square, like
AIC, lets an irrelevant one-parameter effect win about one time in six), and the
discrepancy's prior and the library's bounds, which the fits use anyway, are exactly the
priors it needs. The held-out chi-square of every hypothesis is still computed and
reported beside it, and the shrinkage of the gap is judged on held-out residuals.

Enumeration: the baseline; the discrepancy alone; every identifiable library effect alone,
with and without the discrepancy; then, among the ``screen`` alias classes whose best
member scored highest alone (a first screening pass, so that the count stays near fifty
fits), every pair and triple (one member per class), with and without the discrepancy. A
hypothesis whose one-signed effect (viscous friction, say) fits at zero is the hypothesis
without it, and is not weighed twice.

The effects the discrepancy *holds* (config ``discrepancy_holds``: the pusher's speed gain
and offset and a softer pusher) never sit beside it in one hypothesis. A contact that
differs from the table's changes how a push hands its speed to the box, as they do; beside
the discrepancy they would take up the part of the contact's difference shaped like them,
and an effect fitted for that reason would be weighed as if it had been found. They stay
hypotheses of their own, alone or with other effects, without the discrepancy; where the
discrepancy explains the log as well, the verdict says they cannot be told from it.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from imply.diagnose.inference.aliasing import Aliasing
from imply.diagnose.inference.estimates import EffectEstimate, estimate_fields
from imply.diagnose.inference.fit import JointFit, Problem
from imply.diagnose.inference.screening import fit_candidate, folds
from imply.diagnose.physics.candidates import DISCREPANCY, Candidate, Model
from imply.diagnose.records import Record

NO_EFFECT = "none"  # the label of the hypothesis with neither library effects nor the discrepancy


@dataclass(frozen=True, kw_only=True)
class Hypothesis(Record):
    """One explanation of the log, fitted and scored: its effects, the discrepancy or not, its evidence and weight."""

    label: str  # effects joined by "+", "+discrepancy" where it holds it; "none" for the baseline
    effects: list[str]  # library effects
    discrepancy: bool
    log_evidence: float
    weight: float
    chi2: float  # whitened sum of squares at the fit (noise and the baseline's model error)
    heldout_chi2: float  # the same, each object's fold left out of the effects' fit
    n_parameters: int
    at_bound: list[str]  # library effects at the bound of their library range
    estimates: list[EffectEstimate]  # each library effect's magnitude with its 95% interval


@dataclass(frozen=True)
class FittedHypotheses:
    """Every hypothesis's fit (in the order of :attr:`table`) and the dispersion they were weighed under."""

    fits: list[JointFit]
    table: list[Hypothesis]
    dispersion: float
    singles: list[JointFit]  # each library effect alone, then the discrepancy alone (the screening pass)


def label_of(model: Model) -> str:
    """A hypothesis's label: its library effects (by name) joined by "+", and "discrepancy" where it holds it."""
    names = sorted(c.name for c in model.library) + ([DISCREPANCY] if model.discrepancy is not None else [])
    return "+".join(names) or NO_EFFECT


def log_prior_volume(c: Candidate) -> float:
    """log of the volume of a library effect's range (its uniform prior's reciprocal density)."""
    if c.radius is not None:
        return float(np.log(np.pi * c.radius**2))
    return float(np.sum(np.log(np.asarray(c.hi) - np.asarray(c.lo))))


def rows_fitted(problem: Problem) -> int:
    """Whitened rows in every fit: displacements, the observables beside them where used (outliers left out), and
    the probes' rows."""
    rows = int((problem.w_d > 0).sum()) + (int((problem.w_t > 0).sum()) if problem.use_t else 0)
    return rows + (problem.probe_sd.size if problem.probes is not None else 0)


def dof(problem: Problem, fit: JointFit) -> int:
    """Degrees of freedom left by ``fit``: rows less the objects' free parameters, the launches where freed, and the
    model's."""
    return max(rows_fitted(problem) - problem.k_free * problem.n_obj - problem.n_nuisance - fit.model.dim, 1)


def posterior_precision(fit: JointFit, dispersion: float) -> np.ndarray:
    """A (p, p): the Gauss-Newton Hessian of the profiled log likelihood over the dispersion, plus the prior's."""
    p = fit.theta.size
    return fit.S.sum(0) / dispersion + np.diag(fit.prior) if p else np.zeros((0, 0))


def _laplace(fit: JointFit, dispersion: float, scale: float) -> float:
    """Laplace-approximated log evidence of ``fit``'s model with every Gaussian prior sd times ``scale`` (the
    discrepancy's coefficients moved to their optimum under that prior by one Newton step, the rest held)."""
    theta = fit.theta
    p = theta.size
    prior = fit.prior / scale**2
    S, b = fit.S.sum(0), fit.b.sum(0)
    g = prior > 0
    step = np.zeros(p)
    if g.any() and scale != 1.0:  # the quadratic model of the fit's sum of squares, re-minimised in the prior's block
        A_g = S[np.ix_(g, g)] / dispersion + np.diag(prior[g])
        step[g] = -np.linalg.solve(A_g, b[g] / dispersion + prior[g] * theta[g])
    sse = fit.sse + 2 * b @ step + step @ S @ step
    th = theta + step
    A = S / dispersion + np.diag(prior)
    sign, logdet = np.linalg.slogdet(A + 1e-12 * np.eye(p))
    out = -0.5 * sse / dispersion + 0.5 * p * np.log(2 * np.pi) - 0.5 * (logdet if sign > 0 else np.inf)
    for c, sl in zip(fit.model.candidates, fit.model.slices(), strict=True):
        if c.prior_sd is not None:  # Gaussian prior N(0, sd^2) per component
            sd = c.prior_sd * scale
            out += float(np.sum(-0.5 * th[sl] ** 2 / sd**2 - 0.5 * np.log(2 * np.pi * sd**2)))
        else:
            out -= log_prior_volume(c)
    return float(out)


def log_evidence(fit: JointFit, dispersion: float, scales: int = 1) -> float:
    """Laplace-approximated log evidence of ``fit``'s model (terms common to every hypothesis left out).

    With a discrepancy, its prior sd is not known beforehand (how far a world's contact is from the table's): the
    evidence is averaged over ``scales`` prior sds, halving from the configured one (a log-uniform hyperprior)."""
    if not fit.theta.size:
        return float(-0.5 * fit.sse / dispersion)
    if not (fit.prior > 0).any() or scales <= 1:
        return _laplace(fit, dispersion, 1.0)
    z = np.array([_laplace(fit, dispersion, 0.5**k) for k in range(scales)])
    return float(np.max(z) + np.log(np.mean(np.exp(z - np.max(z)))))


def _weights(log_z: np.ndarray) -> np.ndarray:
    z = np.exp(log_z - np.max(log_z))
    return z / z.sum()


def _estimates(fit: JointFit, dispersion: float) -> list[EffectEstimate]:
    p = fit.theta.size
    cov = np.linalg.pinv(posterior_precision(fit, dispersion)) if p else np.zeros((0, 0))
    return [
        EffectEstimate(**estimate_fields(c, fit.theta[sl], cov[sl, sl]))
        for c, sl in zip(fit.model.candidates, fit.model.slices(), strict=True)
        if c.is_library
    ]


def at_zero(c: Candidate, theta: np.ndarray, rtol: float = 1e-3) -> bool:
    """A one-signed library effect (range [0, hi] or [lo, 0]) fitted at zero: no effect at all."""
    if not c.is_library or c.dim != 1 or 0.0 not in (c.lo[0], c.hi[0]):
        return False
    return bool(abs(float(theta[0])) <= rtol * (c.hi[0] - c.lo[0]))


def at_bound(fit: JointFit) -> list[str]:
    """The library effects of ``fit`` at the bound of their library range that is not zero (their largest
    magnitude): the pushes ask for at least as much as the library holds, so the effect is no cause to state."""
    return [
        c.name
        for c, sl in zip(fit.model.candidates, fit.model.slices(), strict=True)
        if c.bound_direction(fit.theta[sl]) is not None and not at_zero(c, fit.theta[sl])
    ]


def degenerate(fit: JointFit) -> bool:
    """Whether a library effect of ``fit`` sits at zero: the hypothesis is the one without it, counted twice."""
    return any(at_zero(c, fit.theta[sl]) for c, sl in zip(fit.model.candidates, fit.model.slices(), strict=True))


def enumerate_hypotheses(
    problem: Problem,
    base: JointFit,
    pool: list[Candidate],
    *,
    alias: Aliasing,
    max_effects: int,
    screen: int,
    scan: int,
    n_folds: int,
    scales: int = 1,
    held: set[str] = frozenset(),
) -> FittedHypotheses:
    """Fit and weigh every hypothesis (module docstring) of the identifiable candidates in ``pool`` (the discrepancy
    among them where it is used) on top of the baseline fit ``base``; no hypothesis holds an effect of ``held`` (the
    effects the discrepancy holds) beside the discrepancy."""
    disc = next((c for c in pool if not c.is_library), None)
    library = [c for c in pool if c.is_library and alias.effects[c.name].identifiable]
    fits: dict[tuple[str, ...], JointFit] = {(): base}

    def key(cands) -> tuple[str, ...]:
        return tuple(sorted(c.name for c in cands))

    def add(parent: tuple[str, ...], c: Candidate) -> JointFit:
        k = tuple(sorted((*parent, c.name)))
        if k not in fits:
            fits[k] = fit_candidate(problem, fits[parent], c, scan=scan)
        return fits[k]

    singles = []
    for c in library:
        singles.append(add((), c))
    if disc is not None:
        singles.append(add((), disc))
        for c in library:
            if c.name not in held:
                add((c.name,), disc)
    # the screening pass: alias classes ranked by the best score of any member alone (with or without the
    # discrepancy), each class represented in combinations by that member
    dispersion0 = max(1.0, min(f.sse / dof(problem, f) for f in fits.values()))
    score = {}
    for c in library:
        alone = [fits[(c.name,)]] + ([fits[key([c, disc])]] if disc is not None and c.name not in held else [])
        score[c.name] = max(log_evidence(f, dispersion0, scales) for f in alone)
    by_class: dict[str, Candidate] = {}
    for c in sorted(library, key=lambda c: -score[c.name]):
        by_class.setdefault(alias.effects[c.name].cls, c)
    top = list(by_class.values())[: max(screen, 0)]
    for size in range(2, max_effects + 1):
        for combo in itertools.combinations(top, size):
            names = sorted(c.name for c in combo)
            # grown from the best-fitting subset one smaller, the new member added
            parents = [tuple(n for n in names if n != c.name) for c in combo]
            parent = min((p for p in parents if p in fits), key=lambda p: fits[p].sse)
            newcomer = next(c for c in combo if c.name not in parent)
            add(parent, newcomer)
            if disc is not None and not held.intersection(names):
                add(tuple(names), disc)
    # a hypothesis whose effect fits at zero is the smaller one again: weighed once, as the smaller one
    ordered = [f for f in fits.values() if not degenerate(f)]
    dispersion = max(1.0, min(f.sse / dof(problem, f) for f in ordered))
    log_z = np.array([log_evidence(f, dispersion, scales) for f in ordered])
    weights = _weights(log_z)
    fold_of = folds(problem.n_obj, n_folds)
    table = [
        Hypothesis(
            label=label_of(f.model),
            effects=[c.name for c in f.model.library],
            discrepancy=f.model.discrepancy is not None,
            log_evidence=float(z),
            weight=float(w),
            chi2=f.sse,
            heldout_chi2=float(f.heldout_sse_quadratic(fold_of).sum()),
            n_parameters=f.model.dim,
            at_bound=at_bound(f),
            estimates=_estimates(f, dispersion),
        )
        for f, z, w in zip(ordered, log_z, weights, strict=True)
    ]
    order = np.argsort(-weights, kind="stable")
    return FittedHypotheses([ordered[i] for i in order], [table[i] for i in order], dispersion, singles)


def inclusion_weights(table: list[Hypothesis]) -> dict[str, float]:
    """Each library effect's inclusion weight (the summed weight of the hypotheses that hold it), and the
    discrepancy's under "discrepancy"."""
    out: dict[str, float] = {}
    for h in table:
        for n in h.effects + ([DISCREPANCY] if h.discrepancy else []):
            out[n] = out.get(n, 0.0) + h.weight
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))
