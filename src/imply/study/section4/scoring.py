"""Scoring the stand-ins: per-object scores, Table 1's metrics, and the readout-noise sweep (Table 2, top).

:func:`score_rollouts` -> ``scores.csv`` (self and anchored disagreement, implied physics
and log error per stand-in and object); :func:`standin_metrics` -> ``metrics.json``
(Table 1 and the oracle's recovery of mass and friction); :func:`noise_sweep` ->
``noise.json`` (self and anchored AUROC per stand-in and readout-noise level). The result documents are what the registry of reported numbers
(:mod:`imply.paper.registry`) reads the Section 4 numbers from.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from imply import stats
from imply.score import ScoreConfig
from imply.study.section4.config import NoiseConfig
from imply.study.section4.objects import STREAM_NOISE, population, rng_for, truth_arrays
from imply.study.section4.standins import STANDINS, add_readout_noise, rollout_arrays
from imply.table import PushTable


def score_rollouts(
    table: PushTable, objects: pd.DataFrame, truth: pd.DataFrame, rollouts: pd.DataFrame, *, score: ScoreConfig
) -> pd.DataFrame:
    """Scores per (stand-in, object) of the Table 1 rollout sets (jitter: draw 0)."""
    t = truth_arrays(truth, query_speeds=score.query_speeds, calibration_speeds=score.calibration_speeds)
    r = rollout_arrays(rollouts, t["ids"], score.query_speeds)
    ev = population(objects, "eval").set_index("object_id").loc[t["ids"]]
    scorer = score.scorer(table)
    n = len(t["ids"])
    sets = np.concatenate([r[name][:, 0, :] for name in STANDINS])
    sc = scorer.score(
        t["query_speeds"],
        sets,
        np.tile(t["calib_speeds"], (sets.shape[0], 1)),
        np.tile(t["calib"], (len(STANDINS), 1)),
    )
    return pd.DataFrame(
        {
            "standin": np.repeat(STANDINS, n),
            "object_id": np.tile(t["ids"], len(STANDINS)),
            "self_disagreement": sc.self_disagreement,
            "anchored_disagreement": sc.anchored_disagreement,
            "log_error": stats.log_error(sets, np.tile(t["query"], (len(STANDINS), 1)), scorer.floor),
            "mass_hat": sc.mass_hat,
            "friction_hat": sc.friction_hat,
            "anchored_mass_hat": sc.anchored_mass_hat,
            "anchored_friction_hat": sc.anchored_friction_hat,
            "mass": np.tile(ev["mass"].to_numpy(float), len(STANDINS)),
            "friction": np.tile(ev["friction"].to_numpy(float), len(STANDINS)),
        }
    )


def standin_metrics(scores: pd.DataFrame, table: PushTable, *, jitter_sd: float, k_speeds: int) -> dict[str, Any]:
    """Table 1 and the oracle's recovery.

    Returns ``n_objects``, ``k_speeds``, ``jitter_sd``, ``table_shape`` (speeds, masses,
    frictions), ``standins.<name>`` with the mean ``self``, ``anchored`` and ``log_error``
    and, against the oracle, ``auroc_self``, ``auroc_anchored`` and
    ``corr_anchored_error`` (Pearson r of anchored disagreement and log error across
    objects; None for the oracle itself), and ``oracle_recovery`` (R^2 of the oracle's
    implied log mass and log friction against the truth).
    """
    by = {name: scores[scores["standin"] == name].reset_index(drop=True) for name in STANDINS}
    orc = by["oracle"]
    rows: dict[str, dict[str, float | None]] = {}
    for name, f in by.items():
        row: dict[str, float | None] = {
            "self": float(f["self_disagreement"].mean()),
            "anchored": float(f["anchored_disagreement"].mean()),
            "log_error": float(f["log_error"].mean()),
            "auroc_self": None,
            "auroc_anchored": None,
            "corr_anchored_error": None,
        }
        if name != "oracle":
            row["auroc_self"] = stats.auroc(orc["self_disagreement"], f["self_disagreement"])
            row["auroc_anchored"] = stats.auroc(orc["anchored_disagreement"], f["anchored_disagreement"])
            row["corr_anchored_error"] = stats.pearson(f["anchored_disagreement"], f["log_error"])
        rows[name] = row
    return {
        "n_objects": int(len(orc)),
        "k_speeds": int(k_speeds),
        "jitter_sd": float(jitter_sd),
        "table_shape": [int(table.speeds.size), int(table.masses.size), int(table.frictions.size)],
        "standins": rows,
        "oracle_recovery": {
            "mass_r2": stats.r_squared(np.log(orc["mass"]), np.log(orc["mass_hat"])),
            "friction_r2": stats.r_squared(np.log(orc["friction"]), np.log(orc["friction_hat"])),
        },
    }


def noise_sweep(
    table: PushTable,
    truth: pd.DataFrame,
    rollouts: pd.DataFrame,
    *,
    settings: NoiseConfig,
    seed: int,
    score: ScoreConfig,
) -> dict[str, Any]:
    """Table 2 (top): every rollout's displacement times exp(sd z) before scoring.

    The same standard normal draws z are scaled for every sd (common random numbers),
    so the levels differ only by the noise's size; calibration pushes stay exact.
    Returns ``levels``, in increasing sd: each with its ``sd`` and, per stand-in,
    ``mean_self``, ``mean_anchored``, ``auroc_self`` and ``auroc_anchored`` (self and
    anchored disagreement's AUROC against the oracle at the same sd and the same draws;
    None for the oracle itself); and ``smallest_nonzero``, the lowest level with sd > 0
    as ``level`` (its index in ``levels``), ``sd``, ``blind_auroc_self`` and
    ``blind_auroc_anchored`` (all None when no level is above zero), where the claim
    that self-consistency cannot see the object-blind model is checked.
    """
    t = truth_arrays(truth, query_speeds=score.query_speeds, calibration_speeds=score.calibration_speeds)
    r = rollout_arrays(rollouts, t["ids"], score.query_speeds)
    n, k = t["query"].shape
    clean = np.stack([r[name][:, 0, :] for name in STANDINS])  # (4, N, K)
    z = rng_for(seed, STREAM_NOISE).standard_normal(clean.shape)
    sds = sorted(settings.sds)
    noisy = np.concatenate([add_readout_noise(clean, sd, z).reshape(-1, k) for sd in sds])
    scorer = score.scorer(table)
    reps = noisy.shape[0]
    sc = scorer.score(
        t["query_speeds"], noisy, np.tile(t["calib_speeds"], (reps, 1)), np.tile(t["calib"], (reps // n, 1))
    )
    ns = len(STANDINS)
    self_ = sc.self_disagreement.reshape(len(sds), ns, n)
    anch = sc.anchored_disagreement.reshape(len(sds), ns, n)
    levels = []
    for i, sd in enumerate(sds):
        per_standin = {}
        for j, name in enumerate(STANDINS):
            per_standin[name] = {
                "mean_self": float(self_[i, j].mean()),
                "mean_anchored": float(anch[i, j].mean()),
                "auroc_self": None if j == 0 else stats.auroc(self_[i, 0], self_[i, j]),
                "auroc_anchored": None if j == 0 else stats.auroc(anch[i, 0], anch[i, j]),
            }
        levels.append({"sd": float(sd), "standins": per_standin})
    return {"levels": levels, "smallest_nonzero": smallest_nonzero_level(levels)}


def smallest_nonzero_level(levels: list[dict[str, Any]]) -> dict[str, Any]:
    """The lowest readout-noise level above zero of a sweep's ``levels``, and the object-blind model's AUROCs there.

    Returns ``level`` (index into ``levels``), ``sd``, ``blind_auroc_self`` and
    ``blind_auroc_anchored``; every field None when no level has sd > 0.
    """
    nonzero = [i for i, level in enumerate(levels) if level["sd"] > 0]
    if not nonzero:
        return {"level": None, "sd": None, "blind_auroc_self": None, "blind_auroc_anchored": None}
    i = min(nonzero, key=lambda j: levels[j]["sd"])
    blind = levels[i]["standins"]["blind"]
    return {
        "level": i,
        "sd": levels[i]["sd"],
        "blind_auroc_self": blind["auroc_self"],
        "blind_auroc_anchored": blind["auroc_anchored"],
    }
