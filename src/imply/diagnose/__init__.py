"""The sim-to-real gap diagnostic: where a push table disagrees with observed pushes,
which unmodelled effect (:mod:`imply.sim.effects`) explains it, and how far it shrinks.

Modules: :mod:`~imply.diagnose.pushlog` (reading push logs), :mod:`~imply.diagnose.effect_tables`
(effect tables, cached), :mod:`~imply.diagnose.fit` (per-object fits),
:mod:`~imply.diagnose.analysis` (localisation, aliasing, ranking, shrinkage),
:mod:`~imply.diagnose.report` (summary JSON, Markdown report, plots), :mod:`~imply.diagnose.run`
(diagnosing push-log files into report folders), :mod:`~imply.diagnose.benchmark`
(synthetic logs with a withheld effect, and scoring) and
:mod:`~imply.diagnose.benchmark_report` (the benchmark's report and claims).
"""
