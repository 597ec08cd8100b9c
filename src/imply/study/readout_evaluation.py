"""Section 5 data: fitting both displacement readouts on training clips and evaluating them on held-out objects.

:func:`evaluate_readouts` fits the ridge readout (frozen-encoder features of the last
frame -> log displacement) and the frame-difference readout (raw pixels) on every clip
of the training objects that passed the simulator's checks, and evaluates both on every
such clip of the held-out objects: R^2 on log displacement (and on metres), median
error. The result is what the clips stage's numbers are read from (registry sources
``imply.study.readout_evaluation.evaluate_readouts``); :func:`readout_claims` checks the
paper's two readout claims on them.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from imply.data.clips import load_clips
from imply.models.encoder import load_features
from imply.readout import FrameDiffReadout, ReadoutConfig, RidgeReadout, r2_linear, r2_log
from imply.results import Claim, Values

log = logging.getLogger("imply.readout")


@dataclass(frozen=True)
class ClipFiles:
    """One split's files: frames (.npz), metadata (.csv) and cached encoder features (.npz)."""

    frames: Path
    metadata: Path
    features: Path

    @property
    def name(self) -> str:
        return self.frames.stem


@dataclass(frozen=True)
class LoadedSplit:
    frames: np.ndarray  # uint8 (n_clips, T, H, W, 3)
    meta: pd.DataFrame
    tokens: np.ndarray  # (n_clips, T, n_patches, dim)


def load_split_with_features(files: ClipFiles) -> LoadedSplit:
    """A split's frames, metadata and features, checked to hold the same clips."""
    frames, meta = load_clips(files.frames, files.metadata)
    feats = load_features(files.features)
    if not np.array_equal(feats["clip_id"], meta["clip_id"].to_numpy()):
        raise ValueError(f"{files.features} does not hold the clips of {files.frames} (clip ids differ)")
    return LoadedSplit(frames, meta, feats["tokens"])


def evaluate_readouts(
    train: ClipFiles,
    heldout: list[ClipFiles],
    *,
    settings: ReadoutConfig,
    pretrain_episodes: int,
) -> tuple[RidgeReadout, dict[str, Any]]:
    """Fit both readouts on ``train``, evaluate on ``heldout``; (fitted ridge readout, result).

    The result: ``ridge`` (alpha, r2_log, r2_linear, median_abs_error_mm), ``framediff``
    (slope_m_per_px, intercept_m, r2_log, r2_linear, median_abs_error_mm), ``train``
    (episodes, clips, frames, frames_per_clip), ``heldout.<split>`` (objects, clips and
    both readouts' R^2), ``heldout_clips``, ``pretrain.episodes``, ``r2_threshold`` and
    ``features`` (the training features' file name).
    """
    split = load_split_with_features(train)
    ok = split.meta["ok"].to_numpy(dtype=bool)
    d = split.meta["displacement"].to_numpy()
    log.info(
        "fitting on %d training clips (%d failed the simulator's checks and are left out)",
        int(ok.sum()),
        int((~ok).sum()),
    )
    ridge = RidgeReadout.fit(split.tokens[ok, -1], d[ok], alphas=settings.alphas())
    pix = FrameDiffReadout.fit(split.frames[ok], d[ok])
    train_n = {
        "episodes": int(split.meta["object_id"].nunique()),
        "clips": len(split.meta),
        "frames": int(split.frames.shape[0] * split.frames.shape[1]),
        "frames_per_clip": int(split.frames.shape[1]),
    }
    del split

    true, ridge_pred, pix_pred, per_split = [], [], [], {}
    for files in heldout:
        ho = load_split_with_features(files)
        keep = ho.meta["ok"].to_numpy(dtype=bool)
        dt = ho.meta["displacement"].to_numpy()[keep]
        rp = ridge.predict(ho.tokens[keep, -1])
        pp = pix.predict(ho.frames[keep])
        per_split[files.name] = {
            "objects": int(ho.meta["object_id"].nunique()),
            "clips": int(keep.sum()),
            "ridge_r2_log": r2_log(dt, rp),
            "framediff_r2_log": r2_log(dt, pp),
            "ridge_r2_linear": r2_linear(dt, rp),
            "framediff_r2_linear": r2_linear(dt, pp),
        }
        true.append(dt)
        ridge_pred.append(rp)
        pix_pred.append(pp)
        del ho
    true_all, rp_all, pp_all = np.concatenate(true), np.concatenate(ridge_pred), np.concatenate(pix_pred)
    result = {
        "target": "natural log of displacement (metres); R^2 over every clip of the held-out objects",
        "features": Path(train.features).name,
        "ridge": {
            "alpha": ridge.alpha,
            "r2_log": r2_log(true_all, rp_all),
            "r2_linear": r2_linear(true_all, rp_all),
            "median_abs_error_mm": float(np.median(np.abs(rp_all - true_all)) * 1000),
        },
        "framediff": {
            "slope_m_per_px": pix.slope,
            "intercept_m": pix.intercept,
            "r2_log": r2_log(true_all, pp_all),
            "r2_linear": r2_linear(true_all, pp_all),
            "median_abs_error_mm": float(np.median(np.abs(pp_all - true_all)) * 1000),
        },
        "train": train_n,
        "heldout": per_split,
        "heldout_clips": int(true_all.size),
        "pretrain": {"episodes": int(pretrain_episodes)},
        "r2_threshold": settings.r2_threshold,
    }
    log.info(
        "held-out R^2 (log displacement): ridge %.4f (alpha %.3g), frame difference %.4f",
        result["ridge"]["r2_log"],
        ridge.alpha,
        result["framediff"]["r2_log"],
    )
    return ridge, result


def readout_claims(v: Values, results: Mapping[str, Any]) -> list[Claim]:
    """The paper's readout claims at the configured R^2 threshold (``readout.r2_threshold``)."""
    res = results["imply.study.readout_evaluation.evaluate_readouts"]
    threshold = res["r2_threshold"]
    ridge_r2, pix_r2 = v["vjReadoutRTwo"], v["pixReadoutRTwo"]
    return [
        Claim(
            "s5-ridge-readout",
            "5",
            f"A ridge readout from the frozen encoder's last-frame features reads log displacement on held-out "
            f"objects with R^2 >= {threshold} (paper: {v.registry['vjReadoutRTwo'].paper} with V-JEPA 2 ViT-g).",
            bool(ridge_r2 >= threshold),
            f"held-out R^2 {ridge_r2:.3f} ({res['heldout_clips']} clips; encoder features from {res['features']})",
        ),
        Claim(
            "s5-framediff-readout",
            "5",
            f"With a fixed camera, frame differences read log displacement from raw frames with R^2 >= {threshold} "
            f"(paper: {v.registry['pixReadoutRTwo'].paper} on real clips).",
            bool(pix_r2 >= threshold),
            f"held-out R^2 {pix_r2:.3f}; median error {v['pixReadoutMedErrMm']:.1f} mm",
        ),
    ]


def clip_files(frames: str | os.PathLike, metadata: str | os.PathLike, features: str | os.PathLike) -> ClipFiles:
    """:class:`ClipFiles` from three paths."""
    return ClipFiles(Path(frames), Path(metadata), Path(features))
