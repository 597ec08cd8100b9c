"""A diagnosis against a reference session: the standing gap, then what changed since, then how far the gap shrinks.

Three steps, each an ordinary diagnosis or fit (:mod:`imply.diagnose.analysis`):

1. the reference session alone: its verdict is the standing gap (the contact's MJCF change, a
   discrepancy, or nothing), and its leading fit gives each box's (mass, friction); a reference
   without replicate pushes takes the log's noise (:func:`shared_noise`);
2. the new log with that standing gap taken out push by push
   (:func:`imply.diagnose.inference.sessions.against_reference`): its verdict is what changed since the
   reference (nothing; which effect, its size and tier; the contenders; the next pushes);
3. the new session's gap against the table, before and after the cause of the change is added,
   and once the standing gap is described too (:func:`imply.diagnose.inference.sessions.session_shrink`).

In: the new log, the reference, the candidates, the settings, the tables. Out: the diagnosis of
step 2, whose summary carries steps 1 and 3 (:class:`imply.diagnose.inference.sessions.ReferenceReport`).
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

from imply.diagnose.analysis import Diagnosis, DiagnosisConfig, diagnose
from imply.diagnose.conclusion.render import headline, reference_text
from imply.diagnose.conclusion.simulator_check import stated_causes
from imply.diagnose.inference.fit import Problem
from imply.diagnose.inference.noise import estimate_noise
from imply.diagnose.inference.sessions import (
    ReferenceReport,
    StandingGap,
    against_reference,
    cause_shrink,
    stated_part,
)
from imply.diagnose.inputs.pushlog import TRACK_OBSERVABLES, PushLog
from imply.diagnose.physics.candidates import Candidate
from imply.diagnose.physics.effect_tables import EffectTables
from imply.table import PushTable


def shared_noise(log: Problem, reference: Problem, opts: DiagnosisConfig) -> DiagnosisConfig:
    """The settings the reference is diagnosed under: where it has no replicate pushes (a reference session is
    often one push of each), its noise is the log's as the log's replicates measure it (the same robot and
    sensors), where the settings do not state it; otherwise ``opts``."""
    if _replicate_groups(reference) or not _replicate_groups(log):
        return opts
    noise = estimate_noise(log, opts)
    if noise.displacement.source != "replicate pushes":
        return opts
    stated = {"noise_sd": opts.noise_sd or noise.displacement.sd}
    for name in ("stop_time", "pusher_speed"):
        if name in noise.aux and getattr(opts, f"{name}_noise_sd") is None:
            stated[f"{name}_noise_sd"] = noise.aux[name].sd
    track = [n.sd for name, n in noise.aux.items() if name in TRACK_OBSERVABLES]
    if track and opts.track_noise_sd is None:
        stated["track_noise_sd"] = float(np.mean(track))
    return opts.replace(**stated)


def _replicate_groups(problem: Problem) -> int:
    """Conditions pushed more than once."""
    return int((np.bincount(problem.cond) > 1).sum())


def diagnose_against(
    log: PushLog,
    reference: PushLog,
    *,
    table: PushTable,
    etables: EffectTables | None,
    candidates: list[Candidate],
    opts: DiagnosisConfig,
) -> Diagnosis:
    """Diagnose ``log`` against ``reference`` (the module's three steps); the summary's ``seconds`` are the three
    steps' together."""
    t0 = time.perf_counter()
    observables = opts.observables()
    log_problem = Problem.of(log, table, etables, grid=opts.grid, observables=observables)
    ref_problem = Problem.of(reference, table, etables, grid=opts.grid, observables=observables)
    # the reference is read for its standing gap: no next pushes are designed for it
    standing = diagnose(ref_problem, candidates, shared_noise(log_problem, ref_problem, opts), advise=False)
    # the observables a diagnosis of the log alone would read
    used = log_problem.aux
    corrected, pairing = against_reference(log, standing.problem, standing.leading, observables_used=used)
    problem = Problem.of(corrected, table, etables, grid=opts.grid, observables=observables)
    since = diagnose(problem, candidates, opts)
    s = standing.summary
    report = ReferenceReport(
        pushlog=reference.path,
        n_pushes=reference.n,
        **pairing.record_fields(),
        standing=StandingGap(
            pushlog=reference.path,
            n_pushes=reference.n,
            adequacy=str(s.verdict.adequacy),
            identification=str(s.verdict.identification),
            effects=list(s.verdict.effects),
            named=list(s.verdict.named),
            leading=s.verdict.leading,
            headline=headline(s),
            sentence=s.sentence,
            baseline_rms=s.shrinkage.before_rms,
            noise_sd=s.noise.sd,
            discrepancy=s.discrepancy,
        ),
    )
    shrink = cause_shrink(
        pairing.raw, since.problem, since.leading, since.summary.verdict.effects, standing_described=True
    )
    summary = replace(since.summary, pushlog=log.path, reference=report, cause_shrink=shrink)
    summary = replace(
        summary,
        sentence=reference_text(summary),
        seconds=round(time.perf_counter() - t0, 3),
    )
    standing_causes = None
    if s.verdict.effects and standing.leading is not None:
        standing_causes = stated_causes(*stated_part(standing.leading, s.verdict.effects))
    return replace(since, summary=summary, raw=pairing.raw, standing=standing_causes)
