"""The sim-to-real gap diagnostic: where a push table disagrees with observed pushes,
which unmodelled effects (candidates built on :mod:`imply.sim.effects`) explain it, and how
far it shrinks.

Modules: :mod:`~imply.diagnose.pushlog` (reading push logs), :mod:`~imply.diagnose.effect_tables`
(effect and stop-time tables, cached), :mod:`~imply.diagnose.candidates` (the candidate
effects, one or two components each, and how each is named and said in a verdict),
:mod:`~imply.diagnose.fit` (the immutable :class:`~imply.diagnose.fit.Problem` and joint fits
of effects and every object's mass and friction), :mod:`~imply.diagnose.analysis` (the
pipeline :func:`~imply.diagnose.analysis.diagnose` and its typed
:class:`~imply.diagnose.analysis.Summary`), its steps in order
:mod:`~imply.diagnose.noise`, :mod:`~imply.diagnose.localisation`,
:mod:`~imply.diagnose.aliasing`, :mod:`~imply.diagnose.selection`,
:mod:`~imply.diagnose.shrinkage` and :mod:`~imply.diagnose.verdict` (with
:mod:`~imply.diagnose.model_error` and :mod:`~imply.diagnose.estimates` beside them),
:mod:`~imply.diagnose.records` (the typed results' JSON form), :mod:`~imply.diagnose.report`
(summary JSON, Markdown report, plots), :mod:`~imply.diagnose.run` (a checked request of push-log
files diagnosed into report folders), :mod:`~imply.diagnose.benchmark` (scoring against the sealed
labels of the benchmark's logs, which :mod:`imply.realworld` makes) and
:mod:`~imply.diagnose.benchmark_report` (the benchmark's report and claims).
"""
