"""Reading a push's displacement off a clip: a ridge readout from encoder features and a pixel readout.

Ridge readout (latent models, :class:`RidgeReadout`): the input is the **last frame's**
patch tokens of a clip (the box at rest), all patches concatenated in row-major patch
order (no pooling: (n_patches * dim) features, 16 x 64 = 1024 with the CPU default),
standardised per feature; the target is the **log** displacement (natural log of metres),
as the paper reads log slide; alpha is chosen by leave-one-out cross-validation over a
log grid (scikit-learn ``RidgeCV``). It is fit on every clip of the training objects and
evaluated on every clip of the held-out objects (both held-out splits): R^2 of predicted
against true log displacement.

Apply it to predicted tokens (the predictor's rollouts)::

    from imply.readout import load_readout
    readout = load_readout("results/readout/ridge.npz")
    d = readout.predict(last_frame_tokens)   # (N, n_patches, dim) or (N, n_patches*dim) -> (N,) metres

Frame-difference readout (pixel models, :class:`FrameDiffReadout`): with the camera
fixed, the box is the only red thing in the scene. Per pixel, a box saliency
S = max(R - G, 0) (the table is grey, the pusher blue). The difference of the last and
first frames' saliency, weighted by column position, divided by the box's saliency mass
in the first frame, is the shift of the box's centroid in pixels (exact for any
displacement, as long as the box stays in view). A linear map, fit by least squares on
the training clips, turns pixels into metres; evaluated like the ridge readout (R^2 on
log displacement, predictions floored at 1 mm).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar

import numpy as np

from imply.io import write_npz
from imply.options import Config, option

ALPHAS = np.logspace(-2, 5, 29)
FLOOR = 1e-3  # metres; the frame-difference map can go below zero for tiny slides
RIDGE_FORMAT = "imply-ridge-readout-v1"


@dataclass(frozen=True, kw_only=True)
class ReadoutConfig(Config):
    """Config section ``readout``: the ridge's alpha grid (log10, inclusive) and the claims' R^2 threshold."""

    config_key: ClassVar[str] = "readout"

    log10_alpha_min: float = option(-2.0, doc="smallest ridge alpha (log10)")
    log10_alpha_max: float = option(5.0, doc="largest ridge alpha (log10)")
    n_alphas: int = option(29, doc="alphas, log-spaced", minimum=1)
    r2_threshold: float = option(0.95, doc="held-out R^2 the claims ask of a readout", maximum=1)

    def __post_init__(self) -> None:
        if self.log10_alpha_min > self.log10_alpha_max or self.n_alphas < 1:
            raise ValueError("need log10_alpha_min <= log10_alpha_max and n_alphas >= 1")

    def alphas(self) -> np.ndarray:
        return np.logspace(self.log10_alpha_min, self.log10_alpha_max, self.n_alphas)


@dataclass
class RidgeReadout:
    """log displacement = ((x - mean) / scale) . coef + intercept, x = concatenated last-frame tokens."""

    mean: np.ndarray
    scale: np.ndarray
    coef: np.ndarray
    intercept: float
    alpha: float
    n_patches: int
    dim: int

    @classmethod
    def fit(cls, last_tokens: np.ndarray, displacement: np.ndarray, alphas: np.ndarray = ALPHAS) -> RidgeReadout:
        """Fit on (N, n_patches, dim) last-frame tokens and true displacements (metres, > 0)."""
        x = np.asarray(last_tokens, dtype=np.float64)
        if x.ndim != 3:
            raise ValueError("last_tokens must be (N, n_patches, dim)")
        d = np.asarray(displacement, dtype=float)
        if np.any(~np.isfinite(d)) or np.any(d <= 0):
            raise ValueError("displacements must be finite and positive to read log slide")
        n, p, k = x.shape
        flat = x.reshape(n, p * k)
        mean = flat.mean(axis=0)
        scale = flat.std(axis=0)
        scale[scale < 1e-8] = 1.0  # constant features carry nothing; avoid dividing by zero
        z = (flat - mean) / scale
        model = _ridge_cv(alphas).fit(z, np.log(d))
        return cls(
            mean, scale, np.asarray(model.coef_, dtype=float), float(model.intercept_), float(model.alpha_), p, k
        )

    @classmethod
    def fit_centred(cls, tokens: np.ndarray, log_d: np.ndarray, alphas: np.ndarray = ALPHAS) -> RidgeReadout:
        """Fit on (N, P, D) tokens and log slides with features centred but not scaled.

        For reading *predicted* encodings: a feature that barely varies on real frames (a
        background patch) would, once divided by that spread, turn a model's small error
        there into a huge slide.
        """
        n, p, k = np.shape(tokens)
        flat = np.asarray(tokens, dtype=np.float64).reshape(n, p * k)
        mean = flat.mean(axis=0)
        fit = _ridge_cv(alphas).fit(flat - mean, np.asarray(log_d, dtype=float))
        return cls(
            mean, np.ones_like(mean), np.asarray(fit.coef_, float), float(fit.intercept_), float(fit.alpha_), p, k
        )

    def _flat(self, tokens: np.ndarray) -> np.ndarray:
        x = np.asarray(tokens, dtype=np.float64)
        if x.ndim == 3:
            if x.shape[1:] != (self.n_patches, self.dim):
                raise ValueError(f"tokens {x.shape[1:]} do not match the readout's ({self.n_patches}, {self.dim})")
            x = x.reshape(len(x), -1)
        if x.ndim != 2 or x.shape[1] != self.n_patches * self.dim:
            raise ValueError(f"expected (N, {self.n_patches}, {self.dim}) or (N, {self.n_patches * self.dim}) tokens")
        return x

    def predict_log(self, tokens: np.ndarray) -> np.ndarray:
        """Natural log of displacement (metres) from last-frame tokens."""
        return ((self._flat(tokens) - self.mean) / self.scale) @ self.coef + self.intercept

    def predict(self, tokens: np.ndarray) -> np.ndarray:
        """Displacement (metres) from last-frame tokens (N, n_patches, dim) or (N, n_patches*dim)."""
        return np.exp(self.predict_log(tokens))

    def save(self, path: str | os.PathLike) -> None:
        write_npz(
            path,
            format=np.asarray(RIDGE_FORMAT),
            mean=self.mean,
            scale=self.scale,
            coef=self.coef,
            intercept=np.float64(self.intercept),
            alpha=np.float64(self.alpha),
            shape=np.asarray([self.n_patches, self.dim], dtype=np.int64),
        )


def load_readout(path: str | os.PathLike) -> RidgeReadout:
    """The fitted ridge readout written by ``imply study readout fit`` (results/readout/ridge.npz)."""
    path = Path(path)
    with np.load(path) as z:
        if "format" not in z or str(z["format"]) != RIDGE_FORMAT:
            raise ValueError(f"{path}: not a ridge readout file")
        p, k = (int(v) for v in z["shape"])
        return RidgeReadout(z["mean"], z["scale"], z["coef"], float(z["intercept"]), float(z["alpha"]), p, k)


def saliency(frames: np.ndarray) -> np.ndarray:
    """Box saliency max(R - G, 0) of uint8 frames (..., H, W, 3) as float (..., H, W)."""
    f = np.asarray(frames, dtype=np.float32)
    return np.maximum(f[..., 0] - f[..., 1], 0.0)


def frame_diff_shift(first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """Shift (pixels, along image columns) of the box between two frames, from their difference.

    first, last: uint8 (N, H, W, 3). Returns (N,): sum_x x * (S_last - S_first) / sum S_first.
    """
    s0 = saliency(first)
    s1 = saliency(last)
    cols = np.arange(s0.shape[-1], dtype=np.float64)
    moment = ((s1 - s0).sum(axis=-2) * cols).sum(axis=-1)
    mass = s0.sum(axis=(-2, -1))
    return moment / np.maximum(mass, 1e-9)


def saliency_moments(frames: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(column moment, mass) of the box saliency of uint8 frames (..., H, W, 3): sum_x x * S and sum S.

    :func:`frame_diff_shift` of two frames is (moment(last) - moment(first)) / mass(first);
    computed per frame in integers, so a frame's moments are computed once however many
    frames it is compared with (``imply evaluate`` compares every rollout with its context).
    """
    f = np.asarray(frames)
    s = np.maximum(f[..., 0].astype(np.int16) - f[..., 1].astype(np.int16), 0)
    columns = s.sum(axis=-2, dtype=np.int64)
    cols = np.arange(columns.shape[-1], dtype=np.int64)
    return (columns * cols).sum(axis=-1).astype(np.float64), columns.sum(axis=-1).astype(np.float64)


@dataclass
class FrameDiffReadout:
    """displacement (m) = slope * shift_px + intercept, shift from :func:`frame_diff_shift`."""

    slope: float
    intercept: float

    @classmethod
    def fit(cls, clips: np.ndarray, displacement: np.ndarray) -> FrameDiffReadout:
        shift = frame_diff_shift(clips[:, 0], clips[:, -1])
        a, b = np.polyfit(shift, np.asarray(displacement, dtype=float), 1)
        return cls(float(a), float(b))

    def predict(self, clips: np.ndarray) -> np.ndarray:
        """Displacement (metres, floored at 1 mm) of clips (N, T, H, W, 3): last frame against first."""
        return self.from_shift(frame_diff_shift(clips[:, 0], clips[:, -1]))

    def from_shift(self, shift_px: np.ndarray) -> np.ndarray:
        """Displacement (metres, floored at 1 mm) of a box shifted ``shift_px`` pixels along the push."""
        return np.maximum(self.slope * np.asarray(shift_px) + self.intercept, FLOOR)


def _ridge_cv(alphas: np.ndarray):
    """scikit-learn's ``RidgeCV`` over ``alphas``, imported on first use (a second or two): the many commands that
    only read a fitted readout, or none, start without scikit-learn."""
    from sklearn.linear_model import RidgeCV

    return RidgeCV(alphas=alphas)


def _r2_score(true: np.ndarray, pred: np.ndarray) -> float:
    from sklearn.metrics import r2_score

    return float(r2_score(true, pred))


def r2_log(true_d: np.ndarray, pred_d: np.ndarray) -> float:
    """R^2 of predicted against true log displacement."""
    return _r2_score(np.log(np.asarray(true_d, dtype=float)), np.log(np.asarray(pred_d, dtype=float)))


def r2_linear(true_d: np.ndarray, pred_d: np.ndarray) -> float:
    """R^2 of predicted against true displacement in metres."""
    return _r2_score(np.asarray(true_d, dtype=float), np.asarray(pred_d, dtype=float))
