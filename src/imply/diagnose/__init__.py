"""The sim-to-real gap diagnostic: where a push table disagrees with observed pushes, which explanations of it
(sets of unmodelled effects built on :mod:`imply.sim.effects`, with or without a smooth model discrepancy) remain
and how strongly the pushes prefer each, how far the gap shrinks, and which pushes would tell the leaders apart.

Four stages, each a subpackage whose modules import only the stages before it:

1. :mod:`~imply.diagnose.inputs`: what is read (the push log, the boxes' tracks, the calibration probes);
2. :mod:`~imply.diagnose.physics`: what each hypothesis predicts (the candidates, the effect tables);
3. :mod:`~imply.diagnose.inference`: the fits, the noise, the hypotheses weighed, the gap's shrink, a reference
   session's standing gap taken out;
4. :mod:`~imply.diagnose.conclusion`: the verdict, in words, and the next experiments.

Above them: :mod:`~imply.diagnose.analysis` (the pipeline :func:`~imply.diagnose.analysis.diagnose` and its typed
:class:`~imply.diagnose.analysis.Summary`), :mod:`~imply.diagnose.reference` (a diagnosis against a reference
session), :mod:`~imply.diagnose.report` (summary JSON, Markdown report, CSVs, plots) and :mod:`~imply.diagnose.run`
(a checked request of push-log files diagnosed into report folders). Beside them, used by every stage:
:mod:`~imply.diagnose.records` (the typed results' JSON form) and :mod:`~imply.diagnose.tails`. The study's
benchmark that scores the diagnostic lives with the worlds that make its logs, in :mod:`imply.realworld`.
"""
