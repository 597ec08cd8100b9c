"""Section 5 of the paper: the learned action-conditioned predictor's rollouts, scored.

:mod:`~imply.study.section5.rollouts` (the rollout tables as per-object arrays, by model
and context), :mod:`~imply.study.section5.scoring` (Table 3's rows, own against swapped
calibration), :mod:`~imply.study.section5.selection` (choosing among the three candidate
sets) and :mod:`~imply.study.section5.claims`. Scoring imports selection; both import
rollouts.
"""
