"""Stage 2 of the diagnostic, the physics each hypothesis predicts: the candidate effects and what they do to a push.

In: a push log's conditions, the push table, each box's (mass, friction) and a model's parameters. Out: predictions
of every observable (:mod:`~imply.diagnose.physics.prediction`), from the candidates
(:mod:`~imply.diagnose.physics.candidates`: the library's effects and the smooth discrepancy), the effect tables
simulated once and cached (:mod:`~imply.diagnose.physics.effect_tables`), and what each calibration probe reads
under a hypothesis (:mod:`~imply.diagnose.physics.probe_fit`). Nothing is fitted or judged here.
"""
