"""Section 5 selection: choosing, per object, among the calibrated model's three candidate rollout sets.

Each held-out object of the calibrated model has three candidates (own calibration,
swapped, none in context). Rules: lowest anchored disagreement, lowest
self-disagreement, consensus (the per-speed median of the three sets, as in Section
4), a random candidate (``selection_seed``) and the oracle (lowest true log error).
Reported: the mean log error of the chosen sets and how many objects get their
own-calibration set.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from imply.study import metrics, selection_rules

if TYPE_CHECKING:
    from imply.study.section5.scoring import Group

CANDIDATES = ("own", "swap", "none")


def select_candidates(
    groups: dict[str, Group], scored: dict[str, pd.DataFrame], *, floor: float, seed: int
) -> dict[str, Any]:
    """Choose among the own/swap/none candidate sets per object (module docstring).

    Returns ``n`` and, per rule (random, self, anchored, oracle, consensus), the mean
    log ``error`` of the chosen sets and ``own``, how many objects got their
    own-calibration set (None for consensus); ``anchored_minus_oracle`` is the
    anchored rule's error above the oracle's.
    """
    ids = groups["own"].object_ids
    for c in CANDIDATES:
        if not np.array_equal(groups[c].object_ids, ids):
            raise ValueError("candidate sets cover different objects")
    cands = np.stack([np.maximum(groups[c].pred, floor) for c in CANDIDATES], axis=1)  # (N, 3, K)
    true = groups["own"].true
    err = np.stack([scored[c]["log_error"].to_numpy() for c in CANDIDATES], axis=1)
    anch = np.stack([scored[c]["anchored_disagreement"].to_numpy() for c in CANDIDATES], axis=1)
    slf = np.stack([scored[c]["self_disagreement"].to_numpy() for c in CANDIDATES], axis=1)
    n = len(ids)
    rng = np.random.default_rng(seed)
    picks = {
        "random": rng.integers(0, len(CANDIDATES), n),
        "self": selection_rules.select_lowest(slf),
        "anchored": selection_rules.select_lowest(anch),
        "oracle": selection_rules.select_lowest(err),
    }
    out = {"n": n}
    for rule, chosen in picks.items():
        out[rule] = {"error": float(err[np.arange(n), chosen].mean()), "own": int(np.sum(chosen == 0))}
    out["consensus"] = {
        "error": float(metrics.log_error(selection_rules.consensus(cands), true, floor).mean()),
        "own": None,
    }
    out["anchored_minus_oracle"] = out["anchored"]["error"] - out["oracle"]["error"]
    return out
