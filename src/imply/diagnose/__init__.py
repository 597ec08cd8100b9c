"""The sim-to-real gap diagnostic: where a push table disagrees with observed pushes, which explanations of it
(sets of unmodelled effects built on :mod:`imply.sim.effects`, with or without a smooth model discrepancy) remain
and how strongly the pushes prefer each, how far the gap shrinks, and which pushes would tell the leaders apart.

Modules: :mod:`~imply.diagnose.pushlog` (reading push logs), :mod:`~imply.diagnose.effect_tables`
(effect and stop-time tables, cached), :mod:`~imply.diagnose.candidates` (the candidate
effects and the discrepancy), :mod:`~imply.diagnose.fit` (the immutable
:class:`~imply.diagnose.fit.Problem` and joint fits of effects and every object's mass and friction),
:mod:`~imply.diagnose.analysis` (the pipeline :func:`~imply.diagnose.analysis.diagnose` and its typed
:class:`~imply.diagnose.analysis.Summary`), its steps in order :mod:`~imply.diagnose.noise`,
:mod:`~imply.diagnose.localisation`, :mod:`~imply.diagnose.aliasing`, :mod:`~imply.diagnose.hypotheses`
(with :mod:`~imply.diagnose.screening`), :mod:`~imply.diagnose.shrinkage`, :mod:`~imply.diagnose.verdict`
and :mod:`~imply.diagnose.next_pushes` (with :mod:`~imply.diagnose.model_error` and
:mod:`~imply.diagnose.estimates` beside them), :mod:`~imply.diagnose.render` (the verdict in words),
:mod:`~imply.diagnose.records` (the typed results' JSON form), :mod:`~imply.diagnose.report` (summary JSON,
Markdown report, next_pushes.csv, plots), :mod:`~imply.diagnose.run` (a checked request of push-log files
diagnosed into report folders). The study's benchmark that scores the diagnostic lives with the worlds that
make its logs, in :mod:`imply.realworld`.
"""
