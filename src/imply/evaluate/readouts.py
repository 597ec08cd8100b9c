"""One readout per output kind, fitted on the suite's real clips and never on the outputs it reads.

* ``frames`` -- the frame-difference readout (:class:`imply.readout.FrameDiffReadout`):
  the box's shift between the query's first context frame and the model's last frame,
  mapped to metres by a line fitted on the suite's real training clips.
* ``latents`` -- a ridge (:class:`imply.readout.RidgeReadout`) from the model's own
  ``encode()`` of the real training clips' rest frames to their log slides (the paper's
  protocol): the model's encoder is part of the instrument, its rollouts are not.
* ``displacements`` -- taken as given.

Each readout reports its R^2 of log slide and mean |log error| on the suite's check
clips: real clips it was not fitted on (:class:`~imply.evaluate.evaluation.ReadoutInfo`).
A model whose readout cannot read the world is visible there before any of its rollouts
are scored.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from imply.evaluate.evaluation import ReadoutInfo
from imply.evaluate.suite import Suite, SuiteTruth
from imply.readout import FrameDiffReadout, ReadoutConfig, RidgeReadout, saliency_moments

# a rest frame whose box saliency mass is below this share of the context frame's holds no
# box the frame-difference readout can follow (the box left the view, or was never drawn)
MIN_BOX_MASS = 0.5
MAX_PSNR = 99.0  # identical frames: reported as this instead of infinity


@dataclass(frozen=True)
class BatchReadings:
    """(B, K) arrays read off one batch: displacement (m), box_found, saliency_ratio, psnr."""

    displacement: np.ndarray
    box_found: np.ndarray
    saliency_ratio: np.ndarray
    psnr: np.ndarray


class Readout:
    """A fitted readout: :meth:`read` turns a batch of model outputs into :class:`BatchReadings`."""

    info: ReadoutInfo
    fingerprint: str

    def read(self, outputs: np.ndarray, *, index: np.ndarray, true_rest: np.ndarray) -> BatchReadings:
        """outputs: the model's (B, K, ...) array for the suite's objects ``index`` (B,); true_rest: their
        true rest frames, uint8 (B, K, H, W, 3)."""
        raise NotImplementedError


def _check_scores(true_d: np.ndarray, read_d: np.ndarray) -> tuple[float, float]:
    t = np.log(np.asarray(true_d, dtype=float))
    p = np.log(np.asarray(read_d, dtype=float))
    ss = ((t - t.mean()) ** 2).sum()
    r2 = float(1.0 - ((t - p) ** 2).sum() / ss) if ss > 0 else float("nan")
    return r2, float(np.abs(p - t).mean())


def _nan(shape: tuple[int, ...]) -> np.ndarray:
    return np.full(shape, np.nan)


class FrameReadout(Readout):
    def __init__(self, suite: Suite, truth: SuiteTruth) -> None:
        self.line = FrameDiffReadout.fit(suite.train_frames, suite.train_displacement)
        check = self.line.predict(suite.check_frames)
        r2, err = _check_scores(truth.check_displacement, check)
        self.info = ReadoutInfo(
            name="frame difference",
            fitted_on=f"first and rest frames of {len(suite.train_frames)} real training clips of the suite",
            n_fit=len(suite.train_frames),
            n_check=len(suite.check_frames),
            r2_check=r2,
            error_check=err,
        )
        self.fingerprint = f"frames:{self.line.slope!r}:{self.line.intercept!r}"
        # every rollout is compared with its query's first frame and its true rest frame:
        # their box moments once for the suite, (N, K) each
        self._first_moment, self._first_mass = saliency_moments(suite.context_frames[:, :, 0])
        _, self._true_mass = saliency_moments(truth.rest_frames)

    def read(self, outputs: np.ndarray, *, index: np.ndarray, true_rest: np.ndarray) -> BatchReadings:
        rest = outputs[:, :, -1]
        moment, mass = saliency_moments(rest)
        shift = (moment - self._first_moment[index]) / np.maximum(self._first_mass[index], 1e-9)
        d = self.line.from_shift(shift)
        box_found = mass >= MIN_BOX_MASS * self._first_mass[index]
        ratio = mass / np.maximum(self._true_mass[index], 1e-9)
        diff = rest.astype(np.int16) - true_rest.astype(np.int16)
        mse = np.einsum("...ijc,...ijc->...", diff, diff, dtype=np.int64) / np.prod(diff.shape[-3:])
        with np.errstate(divide="ignore"):
            psnr = np.minimum(10.0 * np.log10(255.0**2 / mse), MAX_PSNR)
        return BatchReadings(d, box_found, ratio, psnr)


class LatentReadout(Readout):
    """Ridge from ``encode()`` of real rest frames to log slide, centred but not scaled, read values clipped.

    Two choices make it read *predicted* encodings as well as real ones, both fixed before
    any rollout is read and neither fitted on one: features are centred but not divided by
    their spread on real frames (a feature that barely varies on real frames, a background
    patch, would otherwise get a weight that turns a model's small error there into a huge
    slide: with per-feature scaling the study's predictor read mean log errors above 2,
    centred only about 0.3: docs/notes/section5-recipe.md); and a read log slide
    is clipped to the training slides' range widened by ``MARGIN`` on each side, so one wild
    rollout cannot dominate a mean.
    """

    MARGIN = float(np.log(2.0))

    def __init__(self, train_tokens: np.ndarray, check_tokens: np.ndarray, suite: Suite, truth: SuiteTruth) -> None:
        self.token_shape = tuple(train_tokens.shape[1:])
        if tuple(check_tokens.shape[1:]) != self.token_shape:
            raise ValueError(f"encode() gave check tokens {check_tokens.shape[1:]}, training ones {self.token_shape}")
        flat = np.asarray(train_tokens, dtype=np.float64).reshape(len(train_tokens), 1, -1)
        log_d = np.log(np.asarray(suite.train_displacement, dtype=float))
        self._ridge = RidgeReadout.fit_centred(flat, log_d, alphas=ReadoutConfig().alphas())
        self._log_range = (float(log_d.min() - self.MARGIN), float(log_d.max() + self.MARGIN))
        check = self._predict(np.asarray(check_tokens, dtype=np.float64).reshape(len(check_tokens), -1))
        r2, err = _check_scores(truth.check_displacement, check)
        self.info = ReadoutInfo(
            name="ridge on encode()",
            fitted_on=f"the model's encode() of the rest frames of {len(train_tokens)} real training clips",
            n_fit=len(train_tokens),
            n_check=len(check_tokens),
            r2_check=r2,
            error_check=err,
        )
        digest = hashlib.sha256(self._ridge.coef.tobytes() + self._ridge.mean.tobytes()).hexdigest()[:16]
        self.fingerprint = f"latents:{digest}"

    def _predict(self, flat: np.ndarray) -> np.ndarray:
        return np.exp(np.clip(self._ridge.predict_log(flat), *self._log_range))

    def read(self, outputs: np.ndarray, *, index: np.ndarray, true_rest: np.ndarray) -> BatchReadings:
        b, k = outputs.shape[:2]
        d = self._predict(np.asarray(outputs, dtype=np.float64).reshape(b * k, -1)).reshape(b, k)
        return BatchReadings(d, np.ones((b, k), dtype=bool), _nan((b, k)), _nan((b, k)))


class GivenReadout(Readout):
    info = ReadoutInfo(
        name="as given",
        fitted_on="nothing: the model returns slides",
        n_fit=0,
        n_check=0,
        r2_check=float("nan"),
        error_check=float("nan"),
    )
    fingerprint = "displacements"

    def read(self, outputs: np.ndarray, *, index: np.ndarray, true_rest: np.ndarray) -> BatchReadings:
        b, k = outputs.shape[:2]
        return BatchReadings(np.asarray(outputs, dtype=float), np.ones((b, k), dtype=bool), _nan((b, k)), _nan((b, k)))


def encode_in_batches(encode: Callable[[np.ndarray], np.ndarray], frames: np.ndarray, batch: int) -> np.ndarray:
    """``encode`` over uint8 (N, H, W, 3) frames, ``batch`` at a time, as one float array (N, ...)."""
    parts = []
    for lo in range(0, len(frames), batch):
        out = np.asarray(encode(frames[lo : lo + batch]))
        n = len(frames[lo : lo + batch])
        if out.ndim < 2 or out.shape[0] != n:
            raise ValueError(f"encode() of {n} frames returned shape {out.shape}, expected ({n}, ...)")
        if not np.isfinite(out).all():
            raise ValueError("encode() returned NaN or infinite values on real frames")
        parts.append(out.astype(np.float32, copy=False))
    return np.concatenate(parts)


def codec_checked(readout: Readout, *, suite: Suite, truth: SuiteTruth, encoding: dict) -> Readout:
    """``readout`` (frames) with its check repeated on the suite's real check clips passed through ``encoding``
    (codec, size, fps, bit rate of a submission's videos): a readout that compression breaks shows there."""
    import dataclasses

    from imply.evaluate.video_package import through_codec

    if not isinstance(readout, FrameReadout):
        raise TypeError("only the frame-difference readout reads videos")
    coded = through_codec(suite.check_frames, encoding, suite.frame_shape[:2])
    r2, err = _check_scores(truth.check_displacement, readout.line.predict(coded))
    kbps = encoding.get("bit_rate", 0) / 1000
    readout.info = dataclasses.replace(
        readout.info,
        r2_codec=r2,
        error_codec=err,
        encoding=f"{encoding['codec']}, {encoding['width']}x{encoding['height']} px, {encoding['fps']:g} fps"
        + (f", {kbps:.0f} kb/s" if kbps else ""),
    )
    return readout


def fit_readout(
    kind: str,
    *,
    suite: Suite,
    truth: SuiteTruth,
    train_tokens: np.ndarray | None = None,
    check_tokens: np.ndarray | None = None,
) -> Readout:
    """The readout for ``kind``; latents need the model's encoding of the suite's train and check rest frames."""
    if kind == "frames":
        return FrameReadout(suite, truth)
    if kind == "latents":
        if train_tokens is None or check_tokens is None:
            raise ValueError("a latents readout needs the model's encode() of the suite's real rest frames")
        return LatentReadout(train_tokens, check_tokens, suite, truth)
    if kind == "displacements":
        return GivenReadout()
    raise ValueError(f"unknown output kind {kind!r}")
