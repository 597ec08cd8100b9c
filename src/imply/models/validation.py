"""Per-epoch validation of the predictor on a held-out slice of the training objects.

The slice (``val_objects`` objects, drawn once from ``val_seed``, the same for every
data-order seed) is left out of training. After every epoch each of its objects' query
push is rolled out from its context and read out to a slide with the latent readout,
under the contexts the layout allows: ``own`` and ``swap`` calibration (another
object of the slice, by :func:`imply.models.examples.derangement`) for a calibrated
layout, ``none`` for the context-free one. Reported per context:

* ``log_error``: mean |log predicted - log true slide|;
* ``track_r``: Pearson r across objects of the predicted and the true log slide, both
  taken relative to the training set's typical log slide at the push's speed
  (:mod:`imply.models.object_blind`): the slice's objects are pushed at different
  speeds, and this keeps the speed trend (which any model gets right) out of the
  correlation, as averaging over the same five speeds does in Table 3.

The object-blind baseline's log error on the same pushes is reported beside them, so a
plot shows when the model starts to beat it and when calibration starts to matter.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from imply.models.ac_predictor import ACPredictor
from imply.models.config import Layout
from imply.models.examples import TrainingObjects, derangement, training_objects, training_sequences
from imply.models.features import FeatureSplit
from imply.models.latent_readout import LatentReadout
from imply.models.object_blind import TypicalSlide, typical_slide_of_clips
from imply.models.rollout import final_tokens
from imply.models.sequences import Sequences
from imply.stats import pearson


@dataclass(frozen=True)
class ValidationSlice:
    """The held-out training objects, their sequences per context and their true and typical log slides."""

    sequences: dict[str, Sequences]
    log_true: np.ndarray  # (N,)
    log_typical: np.ndarray  # (N,)


def split_validation(
    split: FeatureSplit, layout: Layout, *, n_objects: int, seed: int
) -> tuple[TrainingObjects, ValidationSlice | None]:
    """(the objects to train on, the validation slice or None when ``n_objects`` is 0)."""
    objects = training_objects(split)
    n = len(objects.object_ids)
    if n_objects == 0:
        return objects, None
    if not 2 <= n_objects < n:
        raise ValueError(f"val_objects {n_objects}: needs 2 .. {n - 1} of the {n} training objects")
    held = np.zeros(n, dtype=bool)
    held[np.random.default_rng(seed).choice(n, size=n_objects, replace=False)] = True
    val = objects.subset(np.flatnonzero(held))
    contexts = {"own": None, "swap": derangement(n_objects, seed)} if layout.calib else {"none": None}
    seqs = {ctx: training_sequences(split, layout, val, calib_of=partner) for ctx, partner in contexts.items()}
    typical: TypicalSlide = typical_slide_of_clips(split.meta[~split.meta["object_id"].isin(val.object_ids)])
    speed = split.meta["speed"].to_numpy(dtype=float)[val.query]
    disp = split.meta["displacement"].to_numpy(dtype=float)[val.query]
    slice_ = ValidationSlice(seqs, np.log(np.maximum(disp, 1e-6)), typical.log_slide(speed))
    return objects.subset(np.flatnonzero(~held)), slice_


def validator(
    slice_: ValidationSlice, readout: LatentReadout, *, batch_size: int = 100
) -> Callable[[ACPredictor], dict[str, float]]:
    """A function of a model giving the slice's metrics (module docstring) as a flat dict."""

    def run(model: ACPredictor) -> dict[str, float]:
        rel_true = slice_.log_true - slice_.log_typical
        out = {"blind_log_error": float(np.mean(np.abs(rel_true)))}
        for ctx, seqs in slice_.sequences.items():
            pred = readout.predict_log(final_tokens(model, seqs, batch_size=batch_size, desc=f"validate {ctx}"))
            out[f"{ctx}_log_error"] = float(np.mean(np.abs(pred - slice_.log_true)))
            out[f"{ctx}_track_r"] = pearson(pred - slice_.log_typical, rel_true)
        return out

    return run
