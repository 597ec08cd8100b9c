"""The sim-to-real gap diagnostic: where a push table disagrees with observed pushes,
which unmodelled effects (candidates built on :mod:`imply.sim.effects`) explain it, and how
far it shrinks.

Modules: :mod:`~imply.diagnose.pushlog` (reading push logs), :mod:`~imply.diagnose.effect_tables`
(effect and stop-time tables, cached), :mod:`~imply.diagnose.candidates` (the candidate
effects, one or two components each), :mod:`~imply.diagnose.fit` (joint fits of effects and
every object's mass and friction), :mod:`~imply.diagnose.analysis` (noise and outliers,
localisation, aliasing, forward selection, shrinkage), :mod:`~imply.diagnose.report`
(summary JSON, Markdown report, plots), :mod:`~imply.diagnose.run` (diagnosing push-log
files into report folders), :mod:`~imply.diagnose.benchmark` (scoring against the sealed
labels of the benchmark's logs, which :mod:`imply.realworld` makes) and
:mod:`~imply.diagnose.benchmark_report` (the benchmark's report and claims).
"""
