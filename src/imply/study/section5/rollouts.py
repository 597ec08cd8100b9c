"""Section 5's rollout tables, read into per-object arrays: one :class:`ContextRollouts` per model and context.

A rollout table (:mod:`imply.models.rollout`) has one row per object, context and push:
the model's rollouts at the query speeds and the two calibration pushes. The study's
held-out tables come from ``imply evaluate`` reports (:func:`rollout_table_of_evaluation`:
the slides its readout, fitted on real clips, read off each rollout); validation builds
them directly (:mod:`~imply.study.section5.validation`). Scoring
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
# imply evaluate's conditions as Section 5's contexts
CONTEXT_OF_CONDITION = {"own": "own", "other": "swap", "none": "none"}


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


def rollout_table_of_evaluation(
    per_object: pd.DataFrame,
    *,
    object_ids: np.ndarray,
    calibration_speeds: np.ndarray,
    calibration_displacement: np.ndarray,
    partner: np.ndarray,
) -> pd.DataFrame:
    """One model's rollout table from its ``imply evaluate`` readings (``per_object.csv``, sample 0).

    ``object_ids`` (N,), ``calibration_speeds`` (2,), ``calibration_displacement`` (N, 2) and
    ``partner`` (N,) come from the suite the model was evaluated on: the calibration rows
    carry each object's own observed pushes (anchoring uses them whatever the context).
    """
    models = per_object["model"].unique()
    if len(models) != 1:
        raise ValueError(f"expected the readings of one model, found {len(models)}")
    df = per_object[per_object["sample"] == 0]
    unknown = sorted(set(df["condition"]) - set(CONTEXT_OF_CONDITION))
    if unknown:
        raise ValueError(f"unknown condition {unknown[0]!r}")
    ids = np.asarray(object_ids).astype(str)
    index = {o: i for i, o in enumerate(ids)}
    missing = sorted(set(df["object_id"].astype(str)) - set(index))
    if missing:
        raise ValueError(f"object {missing[0]} is not in the suite")
    cal_speed = np.asarray(calibration_speeds, dtype=float)
    cal_disp = np.asarray(calibration_displacement, dtype=float)
    speeds = np.sort(df["speed_m_s"].unique())
    tables = []
    for condition, rows in df.groupby("condition", sort=False):
        ctx = CONTEXT_OF_CONDITION[str(condition)]
        objs = rows["object_id"].astype(str).to_numpy()
        first = np.array([index[o] for o in pd.unique(objs)])
        cal = pd.DataFrame(
            {
                "object_id": np.repeat(ids[first], 2),
                "role": "calibration",
                "speed": np.tile(cal_speed, len(first)),
                "displacement": cal_disp[first].reshape(-1),
                "true_displacement": cal_disp[first].reshape(-1),
                "speed_index": -1,
            }
        )
        roll = pd.DataFrame(
            {
                "object_id": objs,
                "role": "rollout",
                "speed": rows["speed_m_s"].to_numpy(float),
                "displacement": rows["read_displacement_m"].to_numpy(float),
                "true_displacement": rows["true_displacement_m"].to_numpy(float),
                "speed_index": np.searchsorted(speeds, rows["speed_m_s"].to_numpy(float)),
            }
        )
        both = pd.concat([cal, roll], ignore_index=True)
        both.insert(1, "context", ctx)
        shown = {"own": ids, "swap": ids[np.asarray(partner)]}.get(ctx)
        both.insert(
            2, "context_object", both["object_id"].map(dict(zip(ids, shown, strict=True))) if shown is not None else ""
        )
        tables.append(both.sort_values(["object_id", "role", "speed_index"], kind="stable"))
    return pd.concat(tables, ignore_index=True)


def suite_folders(specs: list[str]) -> dict[str, str]:
    """``MODEL:FOLDER`` specs (one per model) -> model -> the suite folder its reports were scored on."""
    suites: dict[str, str] = {}
    for spec in specs:
        model, sep, folder = spec.partition(":")
        if not sep or model in suites:
            raise ValueError(f"{spec!r}: expected MODEL:FOLDER, once per model")
        suites[model] = folder
    return suites


def read_evaluations(
    specs: list[str], suites: dict[str, str | Path]
) -> tuple[dict[tuple[str, int], pd.DataFrame], dict[tuple[str, int], dict]]:
    """Rollout tables of ``imply evaluate`` reports named ``MODEL:SEED:FOLDER``, with their readouts.

    ``suites``: model (calib|nocalib) -> the suite folder its report was scored on
    (:func:`suite_folders`). Returns
    (model, seed) -> rollout table, and (model, seed) -> the report's readout description
    (name, what it was fitted on, R^2 and mean |log error| on real check clips). Every seed
    needs both models (ValueError otherwise).
    """
    from imply.evaluate.report import read_report
    from imply.evaluate.suite import load_suite

    loaded = {}
    tables, readouts = {}, {}
    for spec in specs:
        try:
            model, seed_text, folder = spec.split(":", 2)
            seed = int(seed_text)
        except ValueError:
            raise ValueError(f"{spec!r} is not MODEL:SEED:FOLDER") from None
        if model not in MODELS:
            raise ValueError(f"model {model!r} must be calib or nocalib")
        if model not in suites:
            raise ValueError(f"no suite given for the {model} model")
        doc, per_object = read_report(folder)
        if model not in loaded:
            loaded[model] = load_suite(suites[model])
        suite = loaded[model]
        if doc.get("suite") != suite.checksum or len(doc["models"]) != 1:
            raise ValueError(f"{folder}: not one model scored on the suite {suites[model]}")
        tables[(model, seed)] = rollout_table_of_evaluation(
            per_object,
            object_ids=suite.object_ids,
            calibration_speeds=suite.calibration_speeds,
            calibration_displacement=suite.calibration_displacement,
            partner=suite.partner,
        )
        readouts[(model, seed)] = doc["models"][0]["readout"]
    for s in sorted({s for _, s in tables}):
        for m in MODELS:
            if (m, s) not in tables:
                raise ValueError(f"seed {s} lacks the {m} model's evaluation")
    return tables, readouts
