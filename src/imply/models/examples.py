"""Which clips the predictor learns from and is evaluated on: training examples, held-out objects, the swap.

* Training examples (:func:`training_objects`, :func:`training_sequences`): one per
  training object, its query clip, with the object's 2 calibration clips in context for
  the calibrated layout (or, with :meth:`TrainingObjects.every_push_as_query`, three per
  object). Objects with a push that failed the simulator's checks (``ok`` = 0) are left out.
* Held-out objects (:func:`heldout_objects`): each object's 2 calibration clips and its
  query clip at every one of the K query speeds.
* The swap condition (:func:`derangement`): object i takes object ``partner[i]``'s
  calibration clips, a fixed permutation with no fixed point.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np
import pandas as pd

from imply.models.config import Layout
from imply.models.features import FeatureSplit
from imply.models.sequences import Sequences, build_sequences

log = logging.getLogger("imply.models.examples")


def _clip_table(meta: pd.DataFrame) -> pd.DataFrame:
    """The metadata, checked for the columns that pick examples."""
    need = {"clip_id", "object_id", "role", "speed", "displacement"}
    missing = need - set(meta.columns)
    if missing:
        raise ValueError(f"clip metadata lacks column(s): {', '.join(sorted(missing))}")
    return meta


def _ok_objects(meta: pd.DataFrame) -> np.ndarray:
    if "ok" not in meta.columns:
        return meta["object_id"].unique()
    bad = set(meta.loc[meta["ok"] != 1, "object_id"])
    return np.array([o for o in meta["object_id"].unique() if o not in bad])


@dataclass(frozen=True)
class TrainingObjects:
    """The training split's objects with every push ok: clip ids per object, in object order."""

    object_ids: np.ndarray  # (N,)
    query: np.ndarray  # (N,) clip id
    calib: np.ndarray  # (N, 2) clip ids

    def subset(self, rows: np.ndarray) -> TrainingObjects:
        return TrainingObjects(self.object_ids[rows], self.query[rows], self.calib[rows])

    def every_push_as_query(self, speed: np.ndarray) -> TrainingObjects:
        """Three examples per object: each of its three pushes predicted from the other two.

        ``speed``: (n_clips,) commanded speed of every clip; each example's context pair
        is put in order of speed, as the calibration pushes (slow, then fast) are.
        """
        clips = np.concatenate([self.query[:, None], self.calib], axis=1)  # (N, 3)
        queries, contexts = [], []
        for j in range(3):
            ctx = np.delete(clips, j, axis=1)
            swap = speed[ctx[:, 0]] > speed[ctx[:, 1]]
            ctx[swap] = ctx[swap][:, ::-1]
            queries.append(clips[:, j])
            contexts.append(ctx)
        return TrainingObjects(np.tile(self.object_ids, 3), np.concatenate(queries), np.concatenate(contexts, axis=0))


def training_objects(split: FeatureSplit) -> TrainingObjects:
    """The objects of a training split (objects with a push that failed the simulator's checks left out)."""
    meta = _clip_table(split.meta)
    keep = set(_ok_objects(meta))
    if len(keep) < meta["object_id"].nunique():
        log.info("training: leaving out %d object(s) with a failed push", meta["object_id"].nunique() - len(keep))
    meta = meta[meta["object_id"].isin(keep)]
    by_role = meta.pivot_table(index="object_id", columns="role", values="clip_id", aggfunc="first", sort=True)
    return TrainingObjects(
        object_ids=by_role.index.to_numpy(),
        query=by_role["query"].to_numpy(dtype=np.int64),
        calib=by_role[["calibration_0", "calibration_1"]].to_numpy(dtype=np.int64),
    )


def training_sequences(
    split: FeatureSplit,
    layout: Layout,
    objects: TrainingObjects | None = None,
    *,
    calib_of: np.ndarray | None = None,
) -> Sequences:
    """One sequence per training object: its query clip, with calibration clips in context for a calibrated layout.

    ``objects`` defaults to all of :func:`training_objects`; ``calib_of`` (N,) takes
    object ``calib_of[i]``'s calibration clips for object i (the swap condition).
    """
    objects = training_objects(split) if objects is None else objects
    calib = objects.calib if calib_of is None else objects.calib[calib_of]
    return build_sequences(split, layout, query_clip=objects.query, calib_clips=calib)


@dataclass(frozen=True)
class HeldOut:
    """Held-out objects of a split: clip ids per object, in object order."""

    object_ids: np.ndarray  # (N,)
    calib: np.ndarray  # (N, 2) clip ids
    query: np.ndarray  # (N, K) clip ids, by speed_index
    speeds: np.ndarray  # (K,)


def heldout_objects(split: FeatureSplit) -> HeldOut:
    """The held-out objects of a split with every push ok (the others left out, with a warning)."""
    meta = _clip_table(split.meta)
    keep = set(_ok_objects(meta))
    n_all = meta["object_id"].nunique()
    if len(keep) < n_all:
        log.warning("held out: leaving out %d of %d object(s) with a failed push", n_all - len(keep), n_all)
    meta = meta[meta["object_id"].isin(keep)]
    cal = meta[meta["role"].str.startswith("calibration")]
    cal = cal.pivot_table(index="object_id", columns="role", values="clip_id", aggfunc="first", sort=True)
    q = meta[meta["role"] == "query"]
    qp = q.pivot_table(index="object_id", columns="speed_index", values="clip_id", aggfunc="first", sort=True)
    if qp.isna().any().any() or cal.isna().any().any():
        raise ValueError("every held-out object needs both calibration clips and a query clip at every speed")
    speeds = q.groupby("speed_index")["speed"].first().sort_index().to_numpy(dtype=float)
    objs = cal.index.to_numpy()
    return HeldOut(
        object_ids=objs,
        calib=cal.loc[objs, ["calibration_0", "calibration_1"]].to_numpy(dtype=np.int64),
        query=qp.loc[objs].to_numpy(dtype=np.int64),
        speeds=speeds,
    )
