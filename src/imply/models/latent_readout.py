"""Reading a displacement off the predictor's (layer-normed) last-frame tokens.

The predictor lives in layer-normed token space (its inputs and targets are the encoder
tokens through a parameter-free layer norm), so its rollouts are read with
:class:`LatentReadout`, a ridge readout fit like the encoder's (:mod:`imply.readout`:
last-frame tokens, log displacement, alpha by cross-validation), in one of two ways:

* :func:`fit_latent_readout`: on layer-normed real last-frame tokens of the training
  clips (``results/model/readout_ln.npz``; what per-epoch validation reads with);
* :func:`fit_rollout_readout`: on the trained model's own rollouts of its training
  objects (``results/model/<variant>/seed<k>/readout.npz``; see there why).

See the class for the two differences from the encoder's readout.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from imply.io import write_npz
from imply.models.ac_predictor import ACPredictor, normalise_tokens
from imply.models.features import FeatureSplit
from imply.models.rollout import final_tokens
from imply.models.sequences import Sequences
from imply.readout import RidgeReadout, r2_log

log = logging.getLogger("imply.models.latent_readout")

LATENT_FORMAT = "imply-latent-readout-v1"
READOUT_MARGIN = float(np.log(2.0))  # log units the read slide may leave the training range by


@dataclass(frozen=True)
class LatentReadout:
    """Displacement from predicted (layer-normed) last-frame tokens.

    A :class:`imply.readout.RidgeReadout` (log displacement, alpha by cross-validation
    over ``imply.readout.ALPHAS``) fit on layer-normed last-frame tokens, with two
    differences from the encoder's readout, both because it reads *predicted* tokens:
    features are centred but not scaled per feature (layer-normed tokens already share
    one scale; dividing by the tiny spread of background patches would amplify a
    predictor's small errors there into huge displacements), and the read log
    displacement is clipped to the training range widened by ``margin`` (log units) on
    each side, so one wild rollout cannot dominate a mean.
    """

    ridge: RidgeReadout
    log_min: float
    log_max: float

    def predict_log(self, tokens: np.ndarray) -> np.ndarray:
        return np.clip(self.ridge.predict_log(tokens), self.log_min, self.log_max)

    def predict(self, tokens: np.ndarray) -> np.ndarray:
        return np.exp(self.predict_log(tokens))

    def save(self, path: str | Path) -> None:
        r = self.ridge
        write_npz(
            path,
            format=np.asarray(LATENT_FORMAT),
            mean=r.mean,
            scale=r.scale,
            coef=r.coef,
            intercept=np.float64(r.intercept),
            alpha=np.float64(r.alpha),
            shape=np.asarray([r.n_patches, r.dim], dtype=np.int64),
            log_range=np.asarray([self.log_min, self.log_max]),
        )


def load_latent_readout(path: str | Path) -> LatentReadout:
    """A readout written by :meth:`LatentReadout.save` (``imply study model readout`` or ``imply study model train``)."""
    with np.load(path) as z:
        if "format" not in z or str(z["format"]) != LATENT_FORMAT:
            raise ValueError(f"{path}: not a latent readout file (imply study model readout writes one)")
        p, k = (int(v) for v in z["shape"])
        ridge = RidgeReadout(z["mean"], z["scale"], z["coef"], float(z["intercept"]), float(z["alpha"]), p, k)
        lo, hi = (float(v) for v in z["log_range"])
    return LatentReadout(ridge, lo, hi)


def real_last_tokens(split: FeatureSplit, clips: np.ndarray) -> np.ndarray:
    """Layer-normed last-frame tokens of the given clips (row indices or a mask): (N, P, D) float32.

    What the predictor's rest-frame predictions are compared with and the real-token
    readout is fit on.
    """
    return normalise_tokens(torch.from_numpy(split.tokens[clips, -1].astype(np.float32))).numpy()


def _ridge_readout(tokens: np.ndarray, log_d: np.ndarray, margin: float) -> LatentReadout:
    """:class:`LatentReadout` of (N, P, D) tokens to log slides (alpha by cross-validation)."""
    ridge = RidgeReadout.fit_centred(tokens, log_d)
    return LatentReadout(ridge, float(log_d.min() - margin), float(log_d.max() + margin))


def fit_latent_readout(split: FeatureSplit, margin: float = READOUT_MARGIN) -> LatentReadout:
    """:class:`LatentReadout` fit on the layer-normed last-frame tokens of every ok clip."""
    meta = split.meta
    ok = meta["ok"].to_numpy() == 1 if "ok" in meta.columns else np.ones(len(meta), bool)
    ok &= meta["displacement"].to_numpy() > 0
    return _ridge_readout(real_last_tokens(split, ok), np.log(meta["displacement"].to_numpy()[ok]), margin)


def fit_rollout_readout(
    model: ACPredictor,
    seqs: Sequences,
    displacement: np.ndarray,
    *,
    batch_size: int = 200,
    margin: float = READOUT_MARGIN,
) -> LatentReadout:
    """:class:`LatentReadout` fit on the model's own rolled-out last-frame tokens of ``seqs`` (its training sequences).

    ``displacement``: (N,) true slide of each sequence's query push (m, > 0). A readout fit
    on real tokens reads a predicted rest frame as if it were real, and a predicted frame is
    not: where the model cannot tell where the box stops it predicts a blend of the places
    it might, and the real-token readout reads that blend as a shorter slide (and its own
    small errors as object differences). Fit on the model's predictions, the readout maps
    what the model actually says to a slide, still a fixed linear map of the predicted
    tokens: it cannot see the context.
    """
    displacement = np.asarray(displacement, dtype=float)
    if displacement.shape != (len(seqs),) or not np.all(displacement > 0):
        raise ValueError("the rollout readout needs one positive slide per training sequence")
    tokens = final_tokens(model, seqs, batch_size=batch_size, desc="rollout readout")
    return _ridge_readout(tokens, np.log(displacement), margin)


def latent_readout_report(readout: LatentReadout, heldout: dict[str, FeatureSplit]) -> dict:
    """The latent readout's alpha, clipping range and held-out R^2 (log slide) on real layer-normed tokens."""
    report: dict = {"alpha": readout.ridge.alpha, "log_range": [readout.log_min, readout.log_max], "heldout_r2_log": {}}
    for name, split in heldout.items():
        meta = split.meta
        ok = (meta["ok"].to_numpy() == 1) if "ok" in meta.columns else np.ones(len(meta), bool)
        r2 = r2_log(meta["displacement"].to_numpy()[ok], readout.predict(real_last_tokens(split, ok)))
        report["heldout_r2_log"][name] = r2
        log.info("latent readout on %s: held-out R^2 (log slide) %.4f", name, r2)
    return report
