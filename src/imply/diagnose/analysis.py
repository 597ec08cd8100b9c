"""The diagnosis of a push log, as a pipeline of plain steps: where the gap lies, which explanations of it
remain and how strongly the pushes prefer each, how far it shrinks, and which pushes to run next.

:func:`diagnose` runs the steps in order, each a module with an immutable input and output
(on log displacement, and on log stop time where the log has stop times; each observable's
residuals are divided by its noise sd and the model's own error, so sums of squares are
chi-squares):

1. :mod:`~imply.diagnose.inference.noise`: each observable's noise and the gross outliers every fit
   leaves out; the baseline is then fitted under its own model error
   (:mod:`~imply.diagnose.inference.model_error`);
2. :mod:`~imply.diagnose.inference.localisation`: the baseline fit's residuals by band of speed,
   displacement, direction, fitted mass and friction, and by object;
3. :mod:`~imply.diagnose.inference.aliasing`: which candidates these pushes can see and tell apart,
   from each other and from the per-object (mass, friction) fit;
4. :mod:`~imply.diagnose.inference.hypotheses`: every hypothesis (a set of library effects, with or
   without the model discrepancy) fitted and weighed by its evidence;
5. :mod:`~imply.diagnose.inference.shrinkage`: how far the leading hypothesis closes the gap, held out;
6. :mod:`~imply.diagnose.conclusion.verdict`: adequacy and identification, as data;
7. :mod:`~imply.diagnose.conclusion.next_pushes`: the pushes that would best separate the contenders;
8. the :class:`Summary` (``summary.json``), its sentence from :mod:`~imply.diagnose.conclusion.render`,
   which :mod:`~imply.diagnose.report` writes out.

Each step returns a new value; the problem a step fits under (its noise, weights and model
error) is passed to it, never changed behind it (:class:`imply.diagnose.inference.fit.Problem`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from typing import ClassVar

import numpy as np

from imply.diagnose.conclusion.next_pushes import PushDesign, design_pushes
from imply.diagnose.conclusion.render import OBSERVABLE_WORDS, verdict_text
from imply.diagnose.conclusion.simulator_check import Scene, SimulatorCheck, check_causes
from imply.diagnose.conclusion.verdict import Verdict, contradicted, judge
from imply.diagnose.inference.aliasing import Aliasing, aliasing
from imply.diagnose.inference.discrepancy import DiscrepancyReport, describe
from imply.diagnose.inference.estimates import AcceptedEffect, RankedCandidate, accepted_effects, ranked
from imply.diagnose.inference.fit import JointFit, Problem
from imply.diagnose.inference.hypotheses import Hypothesis, enumerate_hypotheses, inclusion_weights, posterior_precision
from imply.diagnose.inference.localisation import Localisation, localise
from imply.diagnose.inference.model_error import model_error
from imply.diagnose.inference.noise import Noise, ObservableNoise, estimate_noise
from imply.diagnose.inference.screening import folds, screened
from imply.diagnose.inference.sessions import ReferenceReport, SessionShrink, against_table, cause_shrink, stated_part
from imply.diagnose.inference.shrinkage import Shrinkage, heldout, shrinkage
from imply.diagnose.inputs.observables import Observables
from imply.diagnose.inputs.pushlog import PushLog
from imply.diagnose.physics.candidates import Candidate, Model, discrepancy_candidate, get
from imply.diagnose.physics.effect_tables import AUX
from imply.diagnose.records import Record, json_field
from imply.options import Config, option


@dataclass(frozen=True, kw_only=True)
class DiagnosisConfig(Config):
    """Settings of the diagnostic (config ``gap.diagnose``)."""

    config_key: ClassVar[str] = "gap.diagnose"

    grid: int = option(101, doc="(m, mu) grid per axis for the objects' global search (at most 61 used)", minimum=11)
    folds: int = option(0, doc="held-out folds of objects (0: leave one object out)", minimum=0)
    alpha: float = option(
        0.05,
        doc="level of the localisation's tests and of the ranking's likelihood-ratio test (Bonferroni)",
        exclusive_minimum=0,
        exclusive_maximum=1,
    )
    alias_cos: float = option(
        0.95, doc="|cos| of projected sensitivities that makes two effects one class", minimum=0, maximum=1
    )
    min_visible: float = option(
        0.005, doc="RMS at an effect's largest magnitude below which it is not identifiable", minimum=0
    )
    fit_alias_share: float = option(
        0.5,
        doc="report a candidate as aliased with the per-object fit when the fit absorbs this share",
        minimum=0,
        maximum=1,
    )
    noise_sd: float | None = option(None, doc="log d noise sd (null: estimated from the log)", exclusive_minimum=0)
    stop_time_noise_sd: float | None = option(
        None, doc="log stop time noise sd (null: estimated from the log)", exclusive_minimum=0
    )
    pusher_speed_noise_sd: float | None = option(
        None, doc="log pusher speed noise sd (null: estimated from the log)", exclusive_minimum=0
    )
    track_noise_sd: float | None = option(
        None,
        doc="noise sd of the log of the track's crossing times, each fraction alike (null: each estimated from "
        "the log)",
        exclusive_minimum=0,
    )
    model_floor: float | None = option(None, doc="the model's own log d error (null: measured)", minimum=0)
    stop_time_floor: float | None = option(None, doc="the model's own stop time error (null: measured)", minimum=0)
    min_share: float = option(
        0.8,
        doc="share of the held-out gap above the noise floor the leading hypothesis must close for the gap to be "
        "explained (below 1 - min_share it is not explained; between, partly)",
        minimum=0.5,
        maximum=1,
    )
    contender_ratio: float = option(
        0.05,
        doc="weight, relative to the leading explanation's, that keeps an explanation in contention",
        exclusive_minimum=0,
        maximum=1,
    )
    use_measured: bool = option(True, doc="use weighed masses where the log has them")
    use_stop_time: bool = option(True, doc="use stop_time where the log has it")
    use_pusher_speed: bool = option(
        False,
        doc="use pusher_speed (the pusher's measured mean speed) where the log has it (off: chosen on the "
        "development sets, where it made null logs of other contact models state a speed error)",
    )
    use_track: bool = option(
        False,
        doc="use the box's track (the times it covers fractions of its travel) where the log has one",
    )
    free_launch: bool = option(
        False,
        doc="leave each push's launch free (a speed of its own per object, speed and direction, profiled out of every "
        "fit), so that only the slide (the displacement against the stop time and the track) reads the effects; "
        "needs an observable beside the displacement",
    )
    use_probes: bool = option(
        True,
        doc="fit the calibration probes beside the log (<stem>.probes.csv) where it has them: free strokes, "
        "friction measurements (as priors with their stated uncertainty) and added-mass pushes",
    )
    max_effects: int = option(3, doc="library effects in one hypothesis at most", minimum=0, maximum=3)
    screen: int = option(4, doc="alias classes, best alone first, whose combinations are fitted", minimum=0)
    outlier_sd: float = option(
        6.0, doc="replicate disagreement (robust sds) that flags a gross outlier", exclusive_minimum=0
    )
    scan: int = option(7, doc="magnitudes scanned per candidate effect", minimum=2)
    discrepancy: bool = option(True, doc="fit a smooth model discrepancy beside the library effects")
    discrepancy_sd: float = option(
        0.1,
        doc="prior sd of each discrepancy coefficient (log units, speed/mass/friction scaled to [-1, 1])",
        exclusive_minimum=0,
    )
    discrepancy_bound: float = option(1.0, doc="largest |discrepancy coefficient| (log units)", exclusive_minimum=0)
    discrepancy_scales: int = option(
        1,
        doc="prior sds of the discrepancy the evidence averages over, halving from discrepancy_sd (1: that one)",
        minimum=1,
    )
    discrepancy_holds: tuple[str, ...] = option(
        ("speed_gain", "speed_offset", "pusher_softness"),
        doc="library effects no hypothesis holds beside the discrepancy: a contact that differs from the table's "
        "changes the pushes as they do, so beside it they would only absorb the contact (chosen on the development "
        "sets)",
        unique=True,
        items={"choices": tuple(c.name for c in get())},
    )
    simulator_check: bool = option(
        True,
        doc="put the stated causes into the simulator: write corrected.xml, re-simulate the log's pushes in it and "
        "in the uncorrected scene, and withdraw the causes where the simulator or the log's probes contradict them "
        "(imply.diagnose.conclusion.simulator_check)",
    )
    simulator_refit: bool = option(
        False,
        doc="refit the stated causes and the boxes in the simulator (mujoco.sysid) for an interval beside the "
        "tables' (imply diagnose --refit); it informs, it does not decide the verdict, and costs tens of passes over "
        "the log, so it is off for the study's hundreds of benchmark logs",
    )
    refit_iterations: int = option(10, doc="Levenberg-Marquardt iterations of the simulator refit at most", minimum=1)
    next_pushes: int = option(12, doc="pushes recommended to separate the contenders", minimum=0)
    next_speeds: int = option(9, doc="candidate speeds of the next pushes, across the table's range", minimum=2)
    next_directions: int = option(12, doc="candidate directions of the next pushes (logs with directions)", minimum=1)

    def observables(self) -> Observables:
        """What every hypothesis's fit reads from a log, as these settings ask."""
        return Observables(
            measured=self.use_measured,
            stop_time=self.use_stop_time,
            pusher_speed=self.use_pusher_speed,
            track=self.use_track,
            probes=self.use_probes,
        )


@dataclass(frozen=True, kw_only=True)
class NoiseReport(Record):
    """The noise the diagnosis assumed: each observable's estimate, the sds used and where they came from."""

    displacement: ObservableNoise
    stop_time: ObservableNoise | None = json_field(omit_none=True, default=None)
    pusher_speed: ObservableNoise | None = json_field(omit_none=True, default=None)
    sd: float
    stop_time_sd: float | None
    pusher_speed_sd: float | None = json_field(omit_none=True, default=None)
    aux_sd: dict[str, float] = field(default_factory=dict)  # every observable beside log d, by name
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
    ranking: list[RankedCandidate]  # every candidate on its own (the screening pass)
    hypotheses: list[Hypothesis]  # every hypothesis fitted, heaviest first
    inclusion: dict[str, float]  # each library effect's (and the discrepancy's) inclusion weight
    dispersion: float  # the chi-square per degree of freedom the weights were computed under (at least 1)
    effects: list[AcceptedEffect]  # the leading hypothesis's library effects
    verdict: Verdict
    sentence: str  # the verdict in words (imply.diagnose.conclusion.render)
    shrinkage: Shrinkage
    options: DiagnosisConfig
    model_floor: dict | None  # the effect tables' measured model floor
    seconds: float
    next_pushes: PushDesign | None = json_field(omit_none=True, default=None)
    discrepancy: DiscrepancyReport | None = json_field(omit_none=True, default=None)
    # where the log was diagnosed against a reference session: the standing gap and the gap's shrink
    reference: ReferenceReport | None = json_field(omit_none=True, default=None)
    # how far the log's gap shrinks once the stated causes alone are added (and, against a reference, once the
    # standing gap is described too)
    cause_shrink: SessionShrink | None = json_field(omit_none=True, default=None)
    # what the simulator and the log's probes say of the stated causes (imply.diagnose.conclusion.simulator_check)
    simulator: SimulatorCheck | None = json_field(omit_none=True, default=None)


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
    pusher_resid_before: np.ndarray | None = None
    pusher_resid_after: np.ndarray | None = None


@dataclass(frozen=True)
class Diagnosis:
    summary: Summary
    residuals: Residuals
    pushlog: PushLog  # the log diagnosed (the next pushes are written in its columns)
    problem: Problem | None = None  # the problem the hypotheses were fitted under (its noise, weights, model error)
    leading: JointFit | None = None  # the leading hypothesis's fit
    # against a reference: the log as pushed (the problem's log has the standing gap taken out), and the standing
    # gap's stated causes at the reference's estimates (native components, by candidate name)
    raw: PushLog | None = None
    standing: dict[str, np.ndarray] | None = None
    corrected_xml: str | None = None  # the corrected scene (simulator_check), written beside the report


def baseline_fit(problem: Problem, opts: DiagnosisConfig) -> tuple[Problem, JointFit]:
    """The table alone, fitted under its own model error: (that problem, the fit)."""
    objects = problem.initial_fit()
    problem = model_error(problem, Model(), np.zeros(0), objects=objects, opts=opts).apply(problem)
    return problem, problem.fit(Model(), np.zeros(0), problem.initial_fit())


def _observables(problem: Problem) -> tuple[list[str], str]:
    used = ["displacement", *problem.aux]
    unused = [a for a in AUX if a not in problem.aux and problem.log.aux(a) is not None]
    if problem.aux:
        names = [OBSERVABLE_WORDS[a] for a in used]
        note = ", ".join(names[:-1]) + " and " + names[-1]
        note += ": every hypothesis had to explain " + ("both" if len(names) == 2 else "them all")
    else:
        note = "displacement only"
    if unused:
        note += " (the log's " + " and ".join(OBSERVABLE_WORDS[a] for a in unused) + " not used)"
    if problem.log.track_note:
        note += "; " + problem.log.track_note
    if problem.launch is not None:
        note += "; each push's launch was left free, so that only the slide read the effects"
    probes = problem.log.probes
    if probes is not None:
        c = probes.counts()
        note += (
            f"; the log's calibration probes ({c['free_stroke']} free strokes, {c['friction']} friction "
            f"measurements, {c['added_mass']} added-mass pushes) "
            + ("entered every fit" if problem.probes is not None else "were read and checked; no fit used them")
        )
    return used, note


def _aux_part(problem: Problem, rt: np.ndarray | None, name: str) -> np.ndarray | None:
    """The residuals of observable ``name`` (n,) out of the aux rows ``rt`` (None where unused)."""
    if rt is None or name not in problem.aux:
        return None
    return rt[problem.aux_rows(name)]


def _outliers(problem: Problem, noise: Noise) -> dict[str, list[Outlier]]:
    out = {"displacement": noise.displacement, **noise.aux}
    return {
        name: [
            Outlier(
                row=int(i),
                object_id=problem.log.objects[problem.obj[i]],
                speed=float(problem.v[i]),
                direction=float(problem.phi[i]),
            )
            for i in est.outliers
        ]
        for name, est in out.items()
    }


def baseline_residuals(problem: Problem, base: JointFit) -> tuple[np.ndarray, np.ndarray | None]:
    """Every push's raw residuals (log d, log T) under the baseline fit ``base``."""
    lm, lu = base.objects.lm[problem.c_obj], base.objects.lu[problem.c_obj]
    return problem.row_residuals(problem.predict(Model(), np.zeros(0), lm, lu))


def diagnose(problem: Problem, candidates: list[Candidate], opts: DiagnosisConfig, *, advise: bool = True) -> Diagnosis:
    """Run every step on a push log's :class:`Problem` (built with :meth:`Problem.of`); ``advise``: design the next
    pushes (step 7; a reference session's diagnosis, read for its standing gap alone, skips it)."""
    t0 = time.perf_counter()
    noise = estimate_noise(problem, opts)  # 1. noise and outliers, then the baseline under them
    problem, base = baseline_fit(noise.apply(problem), opts)
    if opts.free_launch and problem.use_t:
        problem = problem.with_free_launch(base.objects)
        base = problem.fit(Model(), np.zeros(0), base.objects)
    resid_d, resid_t = baseline_residuals(problem, base)
    where = localise(problem, base.objects, resid_d, alpha=opts.alpha)  # 2. where
    pool = list(candidates)
    if opts.discrepancy:
        pool.append(discrepancy_candidate(aux=problem.aux, prior_sd=opts.discrepancy_sd, bound=opts.discrepancy_bound))
    alias = aliasing(problem, pool, fit=base.objects, opts=opts)  # 3. what these pushes can tell apart
    # a two-component effect of which these directions show one combination is fitted along it alone
    pool = [c.restricted(alias.restricted[c.name].direction) if c.name in alias.restricted else c for c in pool]
    hyps = enumerate_hypotheses(
        problem,
        base,
        pool,
        alias=alias,
        max_effects=opts.max_effects,
        screen=opts.screen,
        scan=opts.scan,
        n_folds=opts.folds,
        scales=opts.discrepancy_scales,
        held=set(opts.discrepancy_holds),
    )  # 4. every explanation, weighed
    final = hyps.fits[0]  # the leading hypothesis
    held = heldout(problem, final, opts.folds)  # 5. how far, held out
    shrink = shrinkage(problem, final, resid_d=resid_d, resid_t=resid_t, held=held)
    share = shrink.judged if shrink.judged is not None else shrink.gap_share_closed
    verdict = judge(
        hyps.table, share=share, min_share=opts.min_share, contender_ratio=opts.contender_ratio
    )  # 6. adequacy and identification
    cov = np.linalg.pinv(posterior_precision(final, hyps.dispersion)) if final.model.dim else np.zeros((0, 0))
    effects = accepted_effects(final.model, final.theta, cov=cov, alias=alias)
    disc = describe(problem, final, mimics=alias.mimicked)
    by_label = {h.label: f for h, f in zip(hyps.table, hyps.fits, strict=True)}
    design = (
        design_pushes(
            problem,
            [(c.label, by_label[c.label], c.weight) for c in verdict.contenders],
            n=opts.next_pushes,
            speeds=opts.next_speeds,
            directions=opts.next_directions,
            opts=opts,
        )
        if advise
        else None
    )  # 7. the pushes that would tell the contenders apart
    singles = screened(problem, base, hyps.singles, alpha=opts.alpha, fold_of=folds(problem.n_obj, opts.folds))

    shrunk = cause_shrink(
        problem.log, problem, final, verdict.effects, base=base
    )  # the stated causes' share of the gap

    # 8. the report's summary and residuals
    observables, note = _observables(problem)
    outliers = _outliers(problem, noise)
    summary = Summary(
        pushlog=problem.log.path,
        n_pushes=int(problem.y.size),
        n_objects=int(problem.n_obj),
        has_direction=problem.log.has_direction,
        measured={"mass": problem.fixed_lm is not None, "friction": problem.fixed_lu is not None},
        observables=observables,
        observables_note=note,
        noise=NoiseReport(
            displacement=noise.displacement,
            stop_time=noise.stop_time,
            pusher_speed=noise.aux.get("pusher_speed"),
            sd=problem.noise_d,
            stop_time_sd=noise.aux["stop_time"].sd if "stop_time" in noise.aux else None,
            pusher_speed_sd=noise.aux["pusher_speed"].sd if "pusher_speed" in noise.aux else None,
            aux_sd={name: float(n.sd) for name, n in noise.aux.items()},
            source=noise.displacement.source,
        ),
        outliers=outliers,
        n_outliers=int(sum(len(v) for v in outliers.values())),
        baseline=Baseline(rms=shrink.before_rms, sse_whitened=base.sse),
        localisation=where,
        aliasing=alias,
        ranking=ranked(singles, alias, model_before=Model(), n=problem.n_rows),
        hypotheses=hyps.table,
        inclusion=inclusion_weights(hyps.table),
        dispersion=hyps.dispersion,
        effects=effects,
        verdict=verdict,
        sentence="",
        shrinkage=shrink,
        options=opts,
        model_floor=problem.etables.meta.get("model_floor") if problem.etables is not None else None,
        seconds=round(time.perf_counter() - t0, 3),
        next_pushes=design,
        discrepancy=disc,
        cause_shrink=shrunk,
    )
    summary = replace(summary, sentence=verdict_text(summary))
    with_effects = bool(final.model.dim)
    residuals = Residuals(
        speed=problem.v,
        direction=problem.phi,
        log_d=problem.y,
        resid_before=resid_d,
        resid_after=held.resid_d if with_effects else None,
        flagged=problem.w_d == 0,
        stop_resid_before=_aux_part(problem, resid_t, "stop_time"),
        stop_resid_after=_aux_part(problem, held.resid_t, "stop_time") if with_effects else None,
        pusher_resid_before=_aux_part(problem, resid_t, "pusher_speed"),
        pusher_resid_after=_aux_part(problem, held.resid_t, "pusher_speed") if with_effects else None,
    )
    return Diagnosis(summary=summary, residuals=residuals, pushlog=problem.log, problem=problem, leading=final)


def check_in_simulator(diag: Diagnosis, scene: Scene, *, nthread: int = 0, text=verdict_text) -> Diagnosis:
    """``diag`` with its stated causes put into the simulator (:mod:`imply.diagnose.conclusion.simulator_check`):
    the summary's ``simulator``, the corrected scene's MJCF, and the causes withdrawn where the simulator or the
    probes contradict them (the sentence, ``text`` of the summary, said again). Unchanged where no cause is stated
    or the settings turn the check off."""
    s = diag.summary
    opts = s.options
    if not opts.simulator_check or not s.verdict.effects or diag.problem is None or diag.leading is None:
        return diag
    raw = diag.raw if diag.raw is not None else diag.problem.log
    p, base = against_table(raw, diag.problem)
    model, theta = stated_part(diag.leading, s.verdict.effects)
    floor = opts.model_floor if opts.model_floor is not None else (s.model_floor or {}).get("rms")
    checked = check_causes(
        problem=diag.problem,
        leading=diag.leading,
        raw_problem=p,
        base=base,
        model=model,
        theta=theta,
        standing=diag.standing,
        predicted=s.cause_shrink,
        model_floor=floor,
        alpha=opts.alpha,
        scene=scene,
        refit=opts.simulator_refit,
        iterations=opts.refit_iterations,
        nthread=nthread,
    )
    c = checked.check
    by = [who for who, bad in (("simulator", c.simulator_contradicts), ("probes", c.probes_contradict)) if bad]
    summary = replace(s, simulator=c, verdict=contradicted(s.verdict, by))
    summary = replace(summary, sentence=text(summary))
    return replace(diag, summary=summary, corrected_xml=checked.corrected_xml)
