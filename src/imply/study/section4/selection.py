"""Choosing among candidate rollout sets of mixed quality (Table 2, bottom).

:func:`selection_study` -> ``selection.json`` (per rule: median miss, share within
``within_mm``, how often the oracle's candidate is picked, mean log error; and the
settings) and ``selection_choices.csv`` (every object's candidates and each rule's choice).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from imply import stats
from imply.score import ScoreConfig
from imply.study import selection_rules
from imply.study.section4.config import SelectionConfig
from imply.study.section4.objects import STREAM_SELECTION, rng_for, truth_arrays
from imply.study.section4.standins import STANDINS, add_readout_noise, rollout_arrays
from imply.table import PushTable

# the rules, in table order: the paper's three and the oracle, then two peer rules
RULES = ("first", "consensus", "anchored", "oracle", "self", "medoid")


def selection_study(
    table: PushTable,
    truth: pd.DataFrame,
    rollouts: pd.DataFrame,
    *,
    settings: SelectionConfig,
    seed: int,
    score: ScoreConfig,
) -> tuple[dict[str, Any], pd.DataFrame]:
    """Choose among ``settings.k`` candidate rollout sets per object with each rule of :data:`RULES`.

    Candidates: the oracle's set and k-1 sets drawn uniformly (with replacement) from
    the other stand-ins (each jitter candidate a different jitter draw), each with
    readout noise of sd ``settings.noise_sd``, in shuffled order. The miss is measured
    at ``settings.query_speed`` (one of the query speeds).

    Returns the summary -- ``k``, ``query_speed``, ``noise_sd``, ``within_mm`` and
    ``rules.<rule>``: ``median_miss_mm``, ``share_within`` and ``within_pct`` (its
    percentage), ``picked_oracle`` and ``picked_oracle_pct`` (None for consensus, which
    builds a set instead of picking one), ``mean_log_error`` -- and the per-object choices.
    """
    t = truth_arrays(truth, query_speeds=score.query_speeds, calibration_speeds=score.calibration_speeds)
    r = rollout_arrays(rollouts, t["ids"], score.query_speeds)
    n, k = t["query"].shape
    n_cand = settings.k
    others = [s for s in STANDINS if s != "oracle"]
    if r["jitter"].shape[1] < n_cand - 1:
        raise ValueError(
            f"section4.selection.k={n_cand} needs section4.standins.jitter_draws >= {n_cand - 1}, "
            f"the rollouts have {r['jitter'].shape[1]}"
        )
    qi = np.flatnonzero(np.isclose(t["query_speeds"], settings.query_speed))
    if qi.size != 1:
        raise ValueError(
            f"section4.selection.query_speed {settings.query_speed} is not one of the query speeds "
            f"{list(score.query_speeds)}"
        )
    qi = int(qi[0])
    rng = rng_for(seed, STREAM_SELECTION)
    kinds = np.empty((n, n_cand), dtype=object)
    cands = np.empty((n, n_cand, k))
    kind_pick = rng.integers(0, len(others), size=(n, n_cand - 1))
    order = np.argsort(rng.random((n, n_cand)), axis=1)
    z = rng.standard_normal((n, n_cand, k))
    for i in range(n):
        raw = [("oracle", r["oracle"][i, 0])]
        used_jitter = 0
        for j in kind_pick[i]:
            name = others[j]
            if name == "jitter":
                raw.append((name, r["jitter"][i, used_jitter]))
                used_jitter += 1
            else:
                raw.append((name, r[name][i, 0]))
        for slot, src in enumerate(order[i]):
            kinds[i, slot] = raw[src][0]
            cands[i, slot] = raw[src][1]
    cands = add_readout_noise(cands, settings.noise_sd, z)
    is_oracle = kinds == "oracle"

    scorer = score.scorer(table)
    flat = cands.reshape(-1, k)
    sc = scorer.score(
        t["query_speeds"], flat, np.tile(t["calib_speeds"], (flat.shape[0], 1)), np.repeat(t["calib"], n_cand, 0)
    )
    self_ = sc.self_disagreement.reshape(n, n_cand)
    anch = sc.anchored_disagreement.reshape(n, n_cand)
    chosen = {
        "first": selection_rules.select_first(n),
        "anchored": selection_rules.select_lowest(anch),
        "oracle": np.argmax(is_oracle, axis=1),
        "self": selection_rules.select_lowest(self_),
        "medoid": selection_rules.select_medoid(cands, scorer.floor),
    }
    true_q = t["query"][:, qi]
    summary: dict[str, Any] = {}
    per_object: dict[str, Any] = {"object_id": t["ids"], "candidates": [",".join(row) for row in kinds]}
    for rule in RULES:
        if rule == "consensus":
            sets = selection_rules.consensus(cands)
            picked = None
            idx = np.full(n, -1)
        else:
            idx = chosen[rule]
            sets = selection_rules.take(cands, idx)
            picked = float(np.mean(is_oracle[np.arange(n), idx].astype(float)))
        miss = stats.miss_mm(sets[:, qi], true_q)
        per_object[f"{rule}_choice"] = idx
        per_object[f"{rule}_miss_mm"] = miss
        within = stats.share_within(miss, settings.within_mm)
        summary[rule] = {
            "median_miss_mm": float(np.median(miss)),
            "share_within": within,
            "within_pct": 100.0 * within,
            "picked_oracle": picked,
            "picked_oracle_pct": None if picked is None else 100.0 * picked,
            "mean_log_error": float(stats.log_error(sets, t["query"], scorer.floor).mean()),
        }
    result = {
        "k": settings.k,
        "query_speed": settings.query_speed,
        "noise_sd": settings.noise_sd,
        "within_mm": settings.within_mm,
        "rules": summary,
    }
    return result, pd.DataFrame(per_object)
