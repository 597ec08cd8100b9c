"""The diagnosis of a push log, as a pipeline of plain steps: where the gap lies, which effects explain
it, how far it shrinks.

:func:`diagnose` runs the steps in order, each a module with an immutable input and output
(on log displacement, and on log stop time where the log has stop times; each observable's
residuals are divided by its noise sd and the model's own error, so sums of squares are
chi-squares):

1. :mod:`~imply.diagnose.noise`: each observable's noise and the gross outliers every fit
   leaves out; the baseline is then fitted under its own model error
   (:mod:`~imply.diagnose.model_error`);
2. :mod:`~imply.diagnose.localisation`: the baseline fit's residuals by band of speed,
   displacement, direction, fitted mass and friction, and by object;
3. :mod:`~imply.diagnose.aliasing`: which candidates these pushes can see and tell apart,
   from each other and from the per-object (mass, friction) fit;
4. :mod:`~imply.diagnose.selection`: forward selection of the candidates that qualify;
5. :mod:`~imply.diagnose.shrinkage`: how far the accepted effects close the gap, held out;
6. :mod:`~imply.diagnose.verdict`: the verdict and its one sentence;
7. the :class:`Summary` (``summary.json``) that :mod:`~imply.diagnose.report` writes out.

Each step returns a new value; the problem a step fits under (its noise, weights and model
error) is passed to it, never changed behind it (:class:`imply.diagnose.fit.Problem`).
Every accepted effect is reported with its magnitude (and azimuth for a tilt or an
anisotropy) and 95% interval from the joint fit's curvature (:mod:`~imply.diagnose.estimates`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from imply.diagnose.aliasing import Aliasing, aliasing
from imply.diagnose.candidates import Candidate, Model, discrepancy_candidate
from imply.diagnose.discrepancy import DiscrepancyReport, describe
from imply.diagnose.estimates import AcceptedEffect, RankedCandidate, accepted_effects, ranked
from imply.diagnose.explanations import Explanations, explain
from imply.diagnose.fit import JointFit, Problem
from imply.diagnose.localisation import Localisation, localise
from imply.diagnose.model_error import model_error
from imply.diagnose.noise import Noise, ObservableNoise, estimate_noise
from imply.diagnose.records import Record, json_field
from imply.diagnose.selection import Selection, forward_select
from imply.diagnose.shrinkage import Shrinkage, heldout, shrinkage
from imply.diagnose.verdict import Verdict, judge
from imply.options import Config, option


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
    discrepancy: bool = option(True, doc="fit a smooth model discrepancy beside the library effects")
    discrepancy_sd: float = option(
        0.1, doc="prior sd of each discrepancy coefficient (log units, speed/mass/friction scaled to [-1, 1])",
        exclusive_minimum=0,
    )  # fmt: skip
    discrepancy_bound: float = option(1.0, doc="largest |discrepancy coefficient| (log units)", exclusive_minimum=0)
    alt_margin: float = option(
        6.0, doc="held-out chi-square within which another explanation fits about as well (named beside)", minimum=0
    )


@dataclass(frozen=True, kw_only=True)
class NoiseReport(Record):
    """The noise the diagnosis assumed: each observable's estimate, the sds used and where they came from."""

    displacement: ObservableNoise
    stop_time: ObservableNoise | None = json_field(omit_none=True, default=None)
    sd: float
    stop_time_sd: float | None
    source: str


@dataclass(frozen=True, kw_only=True)
class Outlier(Record):
    """A gross outlier left out of every fit: its row (0-based, in the log's order) and push."""

    row: int
    object_id: str
    speed: float
    direction: float


@dataclass(frozen=True, kw_only=True)
class Baseline(Record):
    """The baseline (table alone) fit: RMS log d residual and whitened sum of squares."""

    rms: float
    sse_whitened: float


@dataclass(frozen=True, kw_only=True)
class SelectionStep(Record):
    """One step of the forward selection: the effects before it, every candidate tried, the one accepted."""

    step: int
    accepted: str | None
    model_before: list[str]
    candidates: list[RankedCandidate]


@dataclass(frozen=True, kw_only=True)
class Summary(Record):
    """What a diagnosis found (``summary.json``)."""

    pushlog: str
    n_pushes: int
    n_objects: int
    has_direction: bool
    measured: dict[str, bool]  # whether the log's mass / friction were held fixed
    observables: list[str]
    observables_note: str
    noise: NoiseReport
    outliers: dict[str, list[Outlier]]  # by observable
    n_outliers: int
    baseline: Baseline
    localisation: Localisation
    aliasing: Aliasing
    ranking: list[RankedCandidate]  # every candidate on its own (the first step)
    selection: list[SelectionStep]
    effects: list[AcceptedEffect]  # the final model's library effects: the verdict's, or the best combination tried
    verdict: Verdict
    shrinkage: Shrinkage
    options: DiagnosisConfig
    model_floor: dict | None  # the effect tables' measured model floor
    seconds: float
    explanations: Explanations | None = json_field(omit_none=True, default=None)
    discrepancy: DiscrepancyReport | None = json_field(omit_none=True, default=None)


@dataclass(frozen=True)
class Residuals:
    """Every push's residuals (log d, and log stop time where used) before and after the effects, held out."""

    speed: np.ndarray
    direction: np.ndarray
    log_d: np.ndarray
    resid_before: np.ndarray
    resid_after: np.ndarray | None  # None without effects
    flagged: np.ndarray  # gross outliers and their replicates, left out
    stop_resid_before: np.ndarray | None
    stop_resid_after: np.ndarray | None


@dataclass(frozen=True)
class Diagnosis:
    summary: Summary
    residuals: Residuals


def baseline_fit(problem: Problem, opts: DiagnosisConfig) -> tuple[Problem, JointFit]:
    """The table alone, fitted under its own model error: (that problem, the fit)."""
    objects = problem.initial_fit()
    problem = model_error(problem, Model(), np.zeros(0), objects=objects, opts=opts).apply(problem)
    return problem, problem.fit(Model(), np.zeros(0), problem.initial_fit())


def _observables(problem: Problem) -> tuple[list[str], str]:
    if problem.log.stop_time is not None and not problem.use_t:
        note = "displacement only (the log's stop times were not used)"
    elif problem.use_t:
        note = "displacement and stop time: every candidate had to explain both"
    else:
        note = "displacement only (the log has no stop_time)"
    return ["displacement"] + (["stop_time"] if problem.use_t else []), note


def _outliers(problem: Problem, noise: Noise) -> dict[str, list[Outlier]]:
    out = {"displacement": noise.displacement}
    if noise.stop_time is not None:
        out["stop_time"] = noise.stop_time
    return {
        name: [
            Outlier(
                row=int(i),
                object_id=problem.log.objects[problem.obj[i]],
                speed=float(problem.v[i]),
                direction=float(problem.phi[i]),
            )
            for i in est.outliers
        ]  # fmt: skip
        for name, est in out.items()
    }


def _path(selection: Selection, alias: Aliasing, n: int) -> list[SelectionStep]:
    """Every step of the forward selection as reported."""
    path = []
    model_before = Model()
    for j, res in enumerate(selection.steps):
        chosen = selection.accepted[j].name if j < len(selection.accepted) else None
        path.append(SelectionStep(step=j + 1, accepted=chosen, model_before=model_before.names,
                                  candidates=ranked(res, alias, model_before=model_before, n=n)))  # fmt: skip
        if chosen:
            model_before = model_before.plus(selection.accepted[j])
    return path


def baseline_residuals(problem: Problem, base: JointFit) -> tuple[np.ndarray, np.ndarray | None]:
    """Every push's raw residuals (log d, log T) under the baseline fit ``base``."""
    lm, lu = base.objects.lm[problem.c_obj], base.objects.lu[problem.c_obj]
    return problem.row_residuals(problem.predict(Model(), np.zeros(0), lm, lu))


def diagnose(problem: Problem, candidates: list[Candidate], opts: DiagnosisConfig) -> Diagnosis:
    """Run every step on a push log's :class:`Problem` (built with :meth:`Problem.of`)."""
    t0 = time.perf_counter()
    noise = estimate_noise(problem, opts)  # 1. noise and outliers, then the baseline under them
    problem, base = baseline_fit(noise.apply(problem), opts)
    resid_d, resid_t = baseline_residuals(problem, base)
    where = localise(problem, base.objects, resid_d, alpha=opts.alpha)  # 2. where
    pool = list(candidates)
    if opts.discrepancy:
        pool.append(discrepancy_candidate(stop_time=problem.use_t, prior_sd=opts.discrepancy_sd,
                                          bound=opts.discrepancy_bound))  # fmt: skip
    alias = aliasing(problem, pool, fit=base.objects, opts=opts)  # 3. what these pushes can tell apart
    # a two-component effect of which these directions show one combination is fitted along it alone
    pool = [c.restricted(alias.restricted[c.name].direction) if c.name in alias.restricted else c for c in pool]
    selection = forward_select(problem, base, pool, alias=alias, opts=opts)  # 4. which terms
    problem = selection.problem  # fitted under the accepted effects' model error
    # 5. what the verdict may state: effects the discrepancy mimics, alternatives, mechanisms outside the library
    expl, final = explain(problem, selection, n_folds=opts.folds, alt_margin=opts.alt_margin, mimics=alias.mimicked,
                          mimic_r=alias.discrepancy_mimics, alpha=opts.alpha)  # fmt: skip
    held = heldout(problem, final, opts.folds)  # 6. how far, held out
    shrink = shrinkage(problem, final, resid_d=resid_d, resid_t=resid_t, held=held)
    effects = accepted_effects(final.model, final.theta, cov=final.covariance() * shrink.dispersion, alias=alias)
    disc = describe(problem, final, mimics=alias.mimicked)
    verdict = judge(selection, effects, shrink=shrink, min_share=opts.min_share, explanations=expl,
                    discrepancy=disc)  # 7. the verdict, in one sentence  # fmt: skip

    # 7. the report's summary and residuals
    observables, note = _observables(problem)
    outliers = _outliers(problem, noise)
    summary = Summary(
        pushlog=problem.log.path, n_pushes=int(problem.y.size), n_objects=int(problem.n_obj),
        has_direction=problem.log.has_direction,
        measured={"mass": problem.fixed_lm is not None, "friction": problem.fixed_lu is not None},
        observables=observables, observables_note=note,
        noise=NoiseReport(displacement=noise.displacement, stop_time=noise.stop_time, sd=problem.noise_d,
                          stop_time_sd=problem.noise_t if problem.use_t else None,
                          source=noise.displacement.source),
        outliers=outliers, n_outliers=int(sum(len(v) for v in outliers.values())),
        baseline=Baseline(rms=shrink.before_rms, sse_whitened=base.sse),
        localisation=where, aliasing=alias,
        ranking=ranked(selection.steps[0], alias, model_before=Model(), n=problem.n_rows) if selection.steps else [],
        selection=_path(selection, alias, problem.n_rows),
        effects=effects, verdict=verdict, shrinkage=shrink, options=opts,
        model_floor=problem.etables.meta.get("model_floor") if problem.etables is not None else None,
        seconds=round(time.perf_counter() - t0, 3), explanations=expl, discrepancy=disc,
    )  # fmt: skip
    with_effects = bool(final.model.dim)
    residuals = Residuals(
        speed=problem.v, direction=problem.phi, log_d=problem.y, resid_before=resid_d,
        resid_after=held.resid_d if with_effects else None, flagged=problem.w_d == 0, stop_resid_before=resid_t,
        stop_resid_after=held.resid_t if with_effects else None,
    )  # fmt: skip
    return Diagnosis(summary=summary, residuals=residuals)
