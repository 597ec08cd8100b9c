"""The IMPLY study, organised by what each piece is about.

* :mod:`~imply.study.selection_rules`: shared by every section (the statistics are
  :mod:`imply.stats`, shared with the models and the paper);
* :mod:`~imply.study.section4`: the controlled validation (objects, stand-ins, scoring,
  selection, claims);
* :mod:`~imply.study.readout_evaluation`: Section 5's readouts on real clips;
* :mod:`~imply.study.section5`: the learned model's rollouts (scoring, selection, claims).

Each step returns a result that the workflow writes as a result document
(:mod:`imply.paper.results`); the reported numbers are read from those by the registry
(:mod:`imply.paper.registry`). The study imports nothing of :mod:`imply.paper`: its
claims are checked on :class:`imply.results.Values` and return :class:`imply.results.Claim`. The model itself lives in :mod:`imply.models`, the
diagnostic in :mod:`imply.diagnose`.
"""
