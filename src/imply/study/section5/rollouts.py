"""Section 5's rollout tables, read into per-object arrays: one :class:`ContextRollouts` per model and context.

A rollout table (:mod:`imply.models.rollout`) has one row per object, context and push:
the model's rollouts at the query speeds and the two calibration pushes. Scoring
(:mod:`~imply.study.section5.scoring`) and selection (:mod:`~imply.study.section5.selection`)
both read these arrays, so neither imports the other.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from imply.models.object_blind import TypicalSlide

MODELS = ("nocalib", "calib")


@dataclass(frozen=True)
class ContextRollouts:
    """One model x context: per-object arrays, objects sorted by id."""

    object_ids: np.ndarray
    speeds: np.ndarray  # (N, K)
    pred: np.ndarray  # (N, K) metres
    true: np.ndarray  # (N, K)
    calib_speeds: np.ndarray  # (N, 2)
    calib_disp: np.ndarray  # (N, 2)


def rollouts_by_context(table: pd.DataFrame) -> dict[str, ContextRollouts]:
    """Split one model's rollout table into its contexts' rollouts (context name -> rollouts)."""
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
        out[str(ctx)] = ContextRollouts(
            object_ids=ids,
            speeds=roll["speed"].to_numpy(float).reshape(len(ids), k),
            pred=roll["displacement"].to_numpy(float).reshape(len(ids), k),
            true=roll["true_displacement"].to_numpy(float).reshape(len(ids), k),
            calib_speeds=cal["speed"].to_numpy(float).reshape(len(ids), c),
            calib_disp=cal["displacement"].to_numpy(float).reshape(len(ids), c),
        )
    return out


def object_blind_rollouts(rollouts: ContextRollouts, typical: TypicalSlide) -> ContextRollouts:
    """The same objects predicted at the typical slide for each speed (the object-blind baseline)."""
    return ContextRollouts(
        object_ids=rollouts.object_ids,
        speeds=rollouts.speeds,
        pred=typical.slide(rollouts.speeds),
        true=rollouts.true,
        calib_speeds=rollouts.calib_speeds,
        calib_disp=rollouts.calib_disp,
    )


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
