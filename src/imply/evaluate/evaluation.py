"""The result of evaluating one world model on a suite: typed, with a JSON form.

:class:`Readings` holds what the readout read off every rollout (and the truth it is
compared with); :class:`Evaluation` holds the scores computed from them
(:mod:`imply.evaluate.metrics`), each number with a bootstrap 95% interval over objects
(:class:`Estimate`). ``Evaluation.to_dict()`` is what ``results.json`` holds for the model.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields, is_dataclass
from typing import Any

import numpy as np


@dataclass(frozen=True)
class Estimate:
    """A number and its bootstrap 95% percentile interval over objects (NaN where undefined)."""

    value: float
    low: float
    high: float

    def format(self, spec: str = ".3f") -> str:
        if not math.isfinite(self.value):
            return "n/a"
        if not (math.isfinite(self.low) and math.isfinite(self.high)):
            return f"{self.value:{spec}}"
        return f"{self.value:{spec}} [{self.low:{spec}}, {self.high:{spec}}]"


@dataclass(frozen=True)
class ReadoutInfo:
    """The instrument that turned the model's outputs into slides.

    name: ``frame difference``, ``ridge on encode()`` or ``as given``. fitted_on: what it
    was fitted on (never the outputs it reads). n_fit, n_check: real clips it was fitted
    and checked on. r2_check, error_check: R^2 of log slide and mean |log error| on the real
    check clips (NaN for displacements, which are taken as given). encoding, r2_codec,
    error_codec: for videos read from files, how they were encoded (codec, size, fps,
    bit rate) and the same check on the real check clips passed through that encoding
    (None and NaN otherwise).
    """

    name: str
    fitted_on: str
    n_fit: int
    n_check: int
    r2_check: float
    error_check: float
    encoding: str | None = None
    r2_codec: float = float("nan")
    error_codec: float = float("nan")


@dataclass(frozen=True)
class ConditionScores:
    """One condition (own, other or none), read on sample set 0 over ``n_objects`` objects.

    track: Pearson r across objects of the mean over K of read log slide against the mean
    true log slide. error: per object the RMS over K of read minus true log slide, averaged.
    self_disagreement, anchored_disagreement: means over objects (anchoring always on the
    object's own observed calibration pushes). corr_self, corr_anchored: each score's
    Pearson r with the per-object error.
    """

    condition: str
    n_objects: int
    track: Estimate
    error: Estimate
    self_disagreement: Estimate
    anchored_disagreement: Estimate
    corr_self: Estimate
    corr_anchored: Estimate


@dataclass(frozen=True)
class OwnVsOther:
    """Share of objects (0..1) whose score is lower with their own calibration than with another's."""

    n_objects: int
    self_disagreement: Estimate
    anchored_disagreement: Estimate


@dataclass(frozen=True)
class SelectionRow:
    """Per object, one candidate chosen by ``rule``; the tracking r and mean log error of the chosen."""

    rule: str
    track: Estimate
    error: Estimate


@dataclass(frozen=True)
class Selection:
    """Choosing among ``n_candidates`` rollout sets per object (``among``: what the candidates are)."""

    among: str
    n_candidates: int
    rows: tuple[SelectionRow, ...]


@dataclass(frozen=True)
class Degenerate:
    """Rollouts that cannot be what they claim, in one condition (counts of sets or rollouts).

    static: sets whose every slide stays below the static limit (a future where nothing
    moves, which consistency scores reward). not_growing: sets whose slide does not grow
    with speed (least-squares slope of log slide on log speed <= 0). no_box: rollouts
    whose rest frame holds no box the readout can find (frames only). unphysical: rollouts
    whose read slide is more than ten times the largest real slide of the suite (no pushed
    box slides that far: a units slip, millimetres for metres, shows this way).
    """

    condition: str
    n_sets: int
    n_rollouts: int
    static: int
    not_growing: int
    no_box: int
    unphysical: int = 0


@dataclass(frozen=True)
class FrameQuality:
    """Generated rest frames against the true ones (frames models, sample set 0, own condition or the first).

    saliency_ratio: box saliency mass of the generated rest frame over the true one's, mean.
    psnr: PSNR (dB) of generated against true rest frame, mean.
    """

    condition: str
    saliency_ratio: Estimate
    psnr: Estimate


@dataclass(frozen=True, eq=False)
class Readings:
    """What was read off every rollout, and the truth it is compared with.

    conditions: the conditions asked, in order. displacement: (n_conditions, S, N, K)
    slide read off each rollout, metres. box_found: same shape, bool (True for
    non-frames kinds). saliency_ratio, psnr: same shape, float (NaN for non-frames kinds).
    true_displacement: (N, K). calibration_speeds (2,), calibration_displacement (N, 2):
    the observed calibration pushes used to anchor. query_speeds: (K,).
    """

    conditions: tuple[str, ...]
    object_ids: np.ndarray
    query_speeds: np.ndarray
    displacement: np.ndarray
    box_found: np.ndarray
    saliency_ratio: np.ndarray
    psnr: np.ndarray
    true_displacement: np.ndarray
    calibration_speeds: np.ndarray
    calibration_displacement: np.ndarray

    @property
    def n_samples(self) -> int:
        return int(self.displacement.shape[1])


@dataclass(frozen=True, eq=False)
class SetScores:
    """Per set arrays of shape (n_conditions, S, N): self and anchored disagreement, log error, mean log slide."""

    self_disagreement: np.ndarray
    anchored_disagreement: np.ndarray
    error: np.ndarray
    mean_log: np.ndarray


@dataclass(frozen=True, eq=False)
class Scores:
    """The scores of one model's readings (:func:`imply.evaluate.metrics.score_readings`); ``sets``, the
    per-set scores they summarise, is kept out of the JSON form."""

    conditions: tuple[ConditionScores, ...]
    own_vs_other: OwnVsOther | None
    selection_conditions: Selection | None
    selection_samples: tuple[Selection, ...]
    spread: dict[str, Estimate]
    degenerate: tuple[Degenerate, ...]
    frame_quality: FrameQuality | None
    sets: SetScores = field(repr=False)


@dataclass(frozen=True, eq=False)
class Evaluation(Scores):
    """Everything the report says about one model: who and what was measured, then its :class:`Scores`
    (``readings`` is kept out of the JSON form)."""

    model: str
    kind: str
    suite: str
    suite_version: int
    readout: ReadoutInfo
    n_objects: int
    n_speeds: int
    n_samples: int
    bootstrap: int
    readings: Readings = field(repr=False)

    def condition(self, name: str) -> ConditionScores | None:
        return next((c for c in self.conditions if c.condition == name), None)

    def to_dict(self) -> dict[str, Any]:
        scores = [f.name for f in fields(Scores) if f.name != "sets"]
        who = [f.name for f in fields(self) if f.name not in scores and f.name not in ("readings", "sets")]
        return {name: _plain(getattr(self, name)) for name in who + scores}


def _plain(obj: Any) -> Any:
    if is_dataclass(obj):
        return {k: _plain(v) for k, v in asdict(obj).items()}
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, tuple | list):
        return [_plain(v) for v in obj]
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    if isinstance(obj, np.generic):
        return _plain(obj.item())
    return obj
