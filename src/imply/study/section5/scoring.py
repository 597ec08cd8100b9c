"""Section 5: scoring the action-conditioned predictor's latent rollouts.

Inputs: the rollout tables of :mod:`imply.models.rollout` (one per trained model: the
calibrated model with contexts own/swap/none, the model trained without calibration
with context none), for each data-order seed, and the push table.

Per model and context (rows of Table 3):

* tracks object r: Pearson correlation across objects of the mean over the K speeds
  of predicted log slide against the mean of true log slide;
* log error: per object the RMS over K of log(predicted) - log(true) (predictions
  floored at ``score.readout_floor``, as :func:`imply.study.metrics.log_error`), averaged;
* self and anchored disagreement (:class:`imply.score.Scorer`; anchoring always uses
  the object's *own* two observed calibration pushes, whatever was in the context),
  averaged over objects, and each one's Pearson correlation across objects with the
  log error.

The object-blind baseline (row ``B``): every held-out object of the calibrated model
predicted at the training set's typical slide for the speed
(:mod:`imply.models.object_blind`), scored the same way; row ``BQ`` is the same on the
held-out objects of the model trained without calibration. A model that uses its
calibration should beat it; a model without calibration can at best match it.

Own against swapped calibration (calibrated model): the percentage of objects whose
disagreement is lower with their own calibration in context than with another
object's, for self and for anchored disagreement. Selection among the three candidate
sets: :mod:`imply.study.section5.selection`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imply.models.object_blind import TypicalSlide
from imply.score import Scorer
from imply.study import metrics
from imply.study.section5.selection import CANDIDATES, select_candidates

log = logging.getLogger("imply.section5")

# rows of Table 3: (key, model, context); the keys are the middle of the vj* number names
ROWS = (
    ("Q", "nocalib", "none"),
    ("C", "calib", "own"),
    ("S", "calib", "swap"),
    ("CQ", "calib", "none"),
)
MODELS = ("nocalib", "calib")


@dataclass
class Group:
    """One model x context: per-object arrays, objects sorted by id."""

    object_ids: np.ndarray
    speeds: np.ndarray  # (N, K)
    pred: np.ndarray  # (N, K) metres
    true: np.ndarray  # (N, K)
    calib_speeds: np.ndarray  # (N, 2)
    calib_disp: np.ndarray  # (N, 2)


def groups_of(table: pd.DataFrame) -> dict[str, Group]:
    """Split a rollout table into per-context groups."""
    out = {}
    for ctx, df in table.groupby("context", sort=True):
        df = df.sort_values(["object_id", "role", "speed_index", "speed"], kind="stable")
        ids = np.array(sorted(df["object_id"].unique()))
        roll = df[df["role"] == "rollout"]
        cal = df[df["role"] == "calibration"]
        k = len(roll) // len(ids)
        c = len(cal) // len(ids)
        if k * len(ids) != len(roll) or c * len(ids) != len(cal):
            raise ValueError(f"context {ctx}: objects have different numbers of pushes")
        out[str(ctx)] = Group(
            object_ids=ids,
            speeds=roll["speed"].to_numpy(float).reshape(len(ids), k),
            pred=roll["displacement"].to_numpy(float).reshape(len(ids), k),
            true=roll["true_displacement"].to_numpy(float).reshape(len(ids), k),
            calib_speeds=cal["speed"].to_numpy(float).reshape(len(ids), c),
            calib_disp=cal["displacement"].to_numpy(float).reshape(len(ids), c),
        )
    return out


def score_group(g: Group, scorer: Scorer) -> pd.DataFrame:
    """Per-object scores and errors of one group."""
    floor = scorer.floor
    pred = np.maximum(np.nan_to_num(g.pred, nan=floor), floor)
    s = scorer.score(g.speeds, pred, g.calib_speeds, g.calib_disp)
    return pd.DataFrame(
        {
            "object_id": g.object_ids,
            "mean_log_pred": np.log(pred).mean(axis=1),
            "mean_log_true": np.log(np.maximum(g.true, floor)).mean(axis=1),
            "log_error": metrics.log_error(pred, g.true, floor),
            "self_disagreement": s.self_disagreement,
            "anchored_disagreement": s.anchored_disagreement,
        }
    )


def summary(per_object: pd.DataFrame) -> dict[str, float]:
    f = per_object
    return {
        "n": int(len(f)),
        "track": metrics.pearson(f["mean_log_pred"], f["mean_log_true"]),
        "error": float(f["log_error"].mean()),
        "self": float(f["self_disagreement"].mean()),
        "anchored": float(f["anchored_disagreement"].mean()),
        "corr_self": metrics.pearson(f["self_disagreement"], f["log_error"]),
        "corr_anchored": metrics.pearson(f["anchored_disagreement"], f["log_error"]),
    }


def own_lt_swap(own: pd.DataFrame, swap: pd.DataFrame) -> dict[str, float]:
    """Percent of objects whose disagreement is lower with own than swapped calibration."""
    if not np.array_equal(own["object_id"].to_numpy(), swap["object_id"].to_numpy()):
        raise ValueError("own and swapped rollouts cover different objects")
    return {
        "self": 100.0 * float(np.mean(own["self_disagreement"].to_numpy() < swap["self_disagreement"].to_numpy())),
        "anchored": 100.0
        * float(np.mean(own["anchored_disagreement"].to_numpy() < swap["anchored_disagreement"].to_numpy())),
    }


def read_rollout_tables(specs: list[str]) -> dict[tuple[str, int], pd.DataFrame]:
    """Rollout tables named ``MODEL:SEED:PATH``; every seed needs both models' (ValueError otherwise)."""
    tables = {}
    for spec in specs:
        try:
            model, seed_text, path = spec.split(":", 2)
            seed = int(seed_text)
        except ValueError:
            raise ValueError(f"{spec!r} is not MODEL:SEED:PATH") from None
        if model not in MODELS:
            raise ValueError(f"model {model!r} must be calib or nocalib")
        if not Path(path).is_file():
            raise ValueError(f"{path} does not exist")
        tables[(model, seed)] = pd.read_csv(path, dtype={"object_id": str, "context": str, "context_object": str})
    for s in sorted({s for _, s in tables}):
        for m in MODELS:
            if (m, s) not in tables:
                raise ValueError(f"seed {s} lacks the {m} model's rollouts")
    return tables


def object_blind_group(g: Group, typical: TypicalSlide) -> Group:
    """The held-out objects of ``g`` predicted at the typical slide for each speed (the object-blind baseline)."""
    return Group(g.object_ids, g.speeds, typical.slide(g.speeds), g.true, g.calib_speeds, g.calib_disp)


def section5_results(
    tables: dict[tuple[str, int], pd.DataFrame],
    scorer: Scorer,
    *,
    seeds: list[int],
    selection_seed: int,
    typical: TypicalSlide,
) -> tuple[dict[str, Any], pd.DataFrame]:
    """All Section 5 results. ``tables``: (model, data-order seed) -> rollout table.

    Returns the result -- ``seeds``, a list in the order given, each with its ``seed``,
    ``rows.<Q|C|S|CQ|B|BQ>`` (n, track, error, self, anchored, corr_self, corr_anchored),
    ``own_lt_swap`` (self, anchored: percent of objects) and ``selection``
    (:func:`imply.study.section5.selection.select_candidates`) -- and the per-object scores
    with seed, model and context columns.
    """
    per_seed: list[dict[str, Any]] = []
    frames = []
    for seed in seeds:
        res: dict[str, Any] = {"seed": int(seed), "rows": {}}
        scored: dict[tuple[str, str], pd.DataFrame] = {}
        groups: dict[str, dict[str, Group]] = {}
        for model in MODELS:
            groups[model] = groups_of(tables[(model, seed)])
            for ctx, g in groups[model].items():
                scored[(model, ctx)] = score_group(g, scorer)
                f = scored[(model, ctx)].copy()
                f.insert(0, "context", ctx)
                f.insert(0, "model", model)
                f.insert(0, "seed", seed)
                frames.append(f)
        blind = {
            key: score_group(object_blind_group(groups[model]["own" if model == "calib" else "none"], typical), scorer)
            for key, model in (("B", "calib"), ("BQ", "nocalib"))
        }
        for key, b in blind.items():
            f = b.copy()
            f.insert(0, "context", "typical")
            f.insert(0, "model", "blind" if key == "B" else "blind_nocalib_objects")
            f.insert(0, "seed", seed)
            frames.append(f)
        for key, model, ctx in ROWS:
            if (model, ctx) in scored:
                res["rows"][key] = summary(scored[(model, ctx)])
        res["rows"].update({key: summary(b) for key, b in blind.items()})
        res["own_lt_swap"] = own_lt_swap(scored[("calib", "own")], scored[("calib", "swap")])
        res["selection"] = select_candidates(
            groups["calib"], {c: scored[("calib", c)] for c in CANDIDATES}, floor=scorer.floor, seed=selection_seed
        )
        per_seed.append(res)
        log.info("seed %d: %s", seed, {k: round(v["track"], 3) for k, v in res["rows"].items()})
    return {"seeds": per_seed}, pd.concat(frames, ignore_index=True)
