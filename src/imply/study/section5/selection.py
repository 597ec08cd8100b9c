"""Section 5 selection: choosing, per object, among the calibrated model's three candidate rollout sets.

Each held-out object of the calibrated model has three candidates (own calibration,
swapped, none in context). Rules: lowest anchored disagreement, lowest
self-disagreement, consensus (the per-speed median of the three sets, as in Section
4), a random candidate (``selection_seed``) and the oracle (lowest true log error).
Reported: the mean log error of the chosen sets and how many objects get their
own-calibration set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from imply import stats
from imply.study import selection_rules
from imply.study.section5.rollouts import ContextRollouts

CANDIDATES = ("own", "swap", "none")


@dataclass(frozen=True)
class RuleOutcome:
    """What one selection rule chose: the chosen sets' mean log error, and how many objects got
    their own-calibration set (None for consensus, which builds a set instead of choosing one)."""

    error: float
    own: int | None


@dataclass(frozen=True)
class CandidateSelection:
    """Every rule's outcome over the ``n`` objects; ``anchored_minus_oracle`` is the anchored
    rule's error above the oracle's."""

    n: int
    random: RuleOutcome
    lowest_self: RuleOutcome
    lowest_anchored: RuleOutcome
    oracle: RuleOutcome
    consensus: RuleOutcome
    anchored_minus_oracle: float


def select_candidates(
    rollouts: dict[str, ContextRollouts], scored: dict[str, pd.DataFrame], *, floor: float, seed: int
) -> CandidateSelection:
    """Choose among the own/swap/none candidate sets per object (module docstring).

    ``rollouts`` and ``scored``: the calibrated model's rollouts and per-object scores by
    context (:data:`CANDIDATES`).
    """
    ids = rollouts["own"].object_ids
    for c in CANDIDATES:
        if not np.array_equal(rollouts[c].object_ids, ids):
            raise ValueError("candidate sets cover different objects")
    cands = np.stack([np.maximum(rollouts[c].pred, floor) for c in CANDIDATES], axis=1)  # (N, 3, K)
    true = rollouts["own"].true
    err = np.stack([scored[c]["log_error"].to_numpy() for c in CANDIDATES], axis=1)
    anch = np.stack([scored[c]["anchored_disagreement"].to_numpy() for c in CANDIDATES], axis=1)
    slf = np.stack([scored[c]["self_disagreement"].to_numpy() for c in CANDIDATES], axis=1)
    n = len(ids)
    rng = np.random.default_rng(seed)
    picks = {
        "random": rng.integers(0, len(CANDIDATES), n),
        "lowest_self": selection_rules.select_lowest(slf),
        "lowest_anchored": selection_rules.select_lowest(anch),
        "oracle": selection_rules.select_lowest(err),
    }
    # own-calibration is candidate 0
    chosen = {
        rule: RuleOutcome(error=float(err[np.arange(n), pick].mean()), own=int(np.sum(pick == 0)))
        for rule, pick in picks.items()
    }
    consensus = RuleOutcome(
        error=float(stats.log_error(selection_rules.consensus(cands), true, floor).mean()), own=None
    )
    return CandidateSelection(
        n=n,
        **chosen,
        consensus=consensus,
        anchored_minus_oracle=chosen["lowest_anchored"].error - chosen["oracle"].error,
    )
