"""Run world models on a suite (or read their rollouts from a file) and score what the readouts read.

Two ways in, one path: a model run in process (:class:`ModelSource`) and a rollouts file
written elsewhere (:class:`FileSource`) both answer the same :class:`RolloutRequest`
batches; from there the readout, the readings and the scores are one code path, so the
same rollouts give the same result whichever way they came in.

:func:`evaluate` is the Python entry point (``imply evaluate`` calls it). Batches read
off a model are cached on disk when a cache folder is given, keyed by the model's name,
kind and batch size, the suite's checksum and the readout's fitted coefficients; an
interrupted evaluation of a slow model resumes where it stopped.
"""

from __future__ import annotations

import hashlib
import logging
from collections.abc import Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
from tqdm.auto import tqdm

from imply.evaluate.config import EvaluateConfig
from imply.evaluate.evaluation import Evaluation, Readings
from imply.evaluate.interface import (
    DEFAULT_BATCH,
    KINDS,
    ModelError,
    RolloutRequest,
    check_model,
    check_output,
    load_model,
    model_name,
)
from imply.evaluate.metrics import score_readings
from imply.evaluate.readouts import BatchReadings, Readout, codec_checked, encode_in_batches, fit_readout
from imply.evaluate.rollouts_file import RolloutsFile, read_rollouts_file
from imply.evaluate.suite import SUITE_VERSION, Suite, SuiteTruth, load_suite, load_truth, suite_table_path
from imply.io import write_npz
from imply.score import ScoreConfig, one_blas_thread
from imply.table import PushTable

log = logging.getLogger("imply.evaluate")


class Source:
    """Where rollouts come from: a model in process or a rollouts file."""

    name: str
    kind: str
    n_samples: int
    batch_size: int
    cache_key: str | None = None
    encoding: dict | None = None  # videos read from lossy files: how they were encoded (codec, size, fps, bit rate)

    def encodings(self, suite: Suite) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(train, check) encodings of the suite's real rest frames (latents only)."""
        return None, None

    def outputs(self, request: RolloutRequest, index: np.ndarray) -> Any:
        raise NotImplementedError


class ModelSource(Source):
    """A model object (see :mod:`imply.evaluate.interface`) run in this process."""

    def __init__(self, model: Any, *, label: str, samples: int) -> None:
        check_model(model, label)
        self.model = model
        self.name = model_name(model, label)
        self.kind = model.kind
        self.batch_size = int(getattr(model, "batch_size", DEFAULT_BATCH))
        stochastic = bool(getattr(model, "stochastic", False))
        self.n_samples = samples if stochastic else 1
        self.cache_key = f"{label}|{self.name}|{self.kind}|{self.batch_size}"

    def encodings(self, suite: Suite) -> tuple[np.ndarray | None, np.ndarray | None]:
        if self.kind != "latents":
            return None, None
        try:
            train = encode_in_batches(self.model.encode, suite.train_frames[:, -1], self.batch_size)
            check = encode_in_batches(self.model.encode, suite.check_frames[:, -1], self.batch_size)
        except ValueError as exc:
            raise ModelError(f"model {self.name}: {exc}") from exc
        return train, check

    def outputs(self, request: RolloutRequest, index: np.ndarray) -> Any:
        return self.model.rollout(request)


class FileSource(Source):
    """Rollouts generated elsewhere, read from a file (:mod:`imply.evaluate.rollouts_file`)."""

    def __init__(self, data: RolloutsFile) -> None:
        self.data = data
        self.encoding = data.encoding
        self.name = data.model
        self.kind = data.kind
        self.n_samples = data.n_samples
        self.batch_size = DEFAULT_BATCH

    def encodings(self, suite: Suite) -> tuple[np.ndarray | None, np.ndarray | None]:
        return self.data.encoded_train, self.data.encoded_check

    def outputs(self, request: RolloutRequest, index: np.ndarray) -> Any:
        return self.data.batch(request.condition, request.sample, index)


def make_request(suite: Suite, index: np.ndarray, *, condition: str, sample: int) -> RolloutRequest:
    """The request for objects ``index`` of the suite in ``condition``, sample set ``sample``."""
    shown = suite.partner[index] if condition == "other" else index
    calibrated = condition != "none"
    return RolloutRequest(
        object_ids=tuple(str(x) for x in suite.object_ids[index]),
        condition=condition,
        sample=int(sample),
        query_speeds=suite.query_speeds,
        context_frames=suite.context_frames[index],
        calibration_speeds=suite.calibration_speeds if calibrated else None,
        calibration_frames=suite.calibration_frames[shown] if calibrated else None,
        calibration_displacement=suite.calibration_displacement[shown] if calibrated else None,
        frame_times=suite.frame_times,
        metres_per_pixel=suite.metres_per_pixel,
    )


class BatchCache:
    """Readings of finished batches, one .npz each, in a folder named by the source and readout."""

    def __init__(self, root: Path | None, key: str | None) -> None:
        self.folder = root / hashlib.sha256(key.encode()).hexdigest()[:16] if root is not None and key else None

    def _path(self, condition: str, sample: int, lo: int) -> Path:
        return self.folder / f"{condition}-s{sample:04d}-o{lo:06d}.npz"

    def load(self, condition: str, sample: int, lo: int) -> BatchReadings | None:
        if self.folder is None:
            return None
        path = self._path(condition, sample, lo)
        try:
            with np.load(path) as z:
                return BatchReadings(z["displacement"], z["box_found"], z["saliency_ratio"], z["psnr"])
        except (OSError, KeyError, ValueError):
            return None  # absent or unreadable (a kill mid-write leaves no file: writes are atomic)

    def save(self, condition: str, sample: int, lo: int, r: BatchReadings) -> None:
        if self.folder is None:
            return
        write_npz(
            self._path(condition, sample, lo),
            displacement=r.displacement,
            box_found=r.box_found,
            saliency_ratio=r.saliency_ratio,
            psnr=r.psnr,
        )


def read_source(
    source: Source,
    *,
    suite: Suite,
    truth: SuiteTruth,
    readout: Readout,
    conditions: Sequence[str],
    cache_root: Path | None = None,
    progress: bool = False,
) -> Readings:
    """Ask ``source`` for every batch of the suite and read each with ``readout``."""
    n, k = suite.n_objects, suite.n_speeds
    c, s = len(conditions), source.n_samples
    shape = (c, s, n, k)
    disp = np.empty(shape)
    box = np.empty(shape, dtype=bool)
    ratio = np.empty(shape)
    psnr = np.empty(shape)
    cache = BatchCache(
        cache_root, f"{source.cache_key}|{suite.checksum}|{readout.fingerprint}" if source.cache_key else None
    )
    starts = range(0, n, source.batch_size)
    token_shape = getattr(readout, "token_shape", None)
    bar = tqdm(total=c * s * len(starts), desc=f"evaluate {source.name}", unit="batch", disable=not progress)
    for ci, condition in enumerate(conditions):
        for sample in range(s):
            for lo in starts:
                index = np.arange(lo, min(lo + source.batch_size, n))
                got = cache.load(condition, sample, lo)
                if got is None:
                    request = make_request(suite, index, condition=condition, sample=sample)
                    out = check_output(
                        source.outputs(request, index),
                        kind=source.kind,
                        request=request,
                        frame_shape=suite.frame_shape,
                        token_shape=token_shape,
                    )
                    got = readout.read(out, index=index, true_rest=truth.rest_frames[index])
                    cache.save(condition, sample, lo, got)
                sl = (ci, sample, slice(lo, lo + len(index)))
                disp[sl], box[sl], ratio[sl], psnr[sl] = got.displacement, got.box_found, got.saliency_ratio, got.psnr
                bar.update()
    bar.close()
    return Readings(
        conditions=tuple(conditions),
        object_ids=suite.object_ids,
        query_speeds=suite.query_speeds,
        displacement=disp,
        box_found=box,
        saliency_ratio=ratio,
        psnr=psnr,
        true_displacement=truth.displacement,
        calibration_speeds=suite.calibration_speeds,
        calibration_displacement=suite.calibration_displacement,
    )


def evaluate_source(
    source: Source,
    *,
    suite: Suite,
    truth: SuiteTruth,
    table: PushTable,
    settings: EvaluateConfig,
    score: ScoreConfig,
    cache_root: Path | None = None,
    progress: bool = False,
) -> Evaluation:
    """One source through readout, readings and scores."""
    if source.kind not in KINDS:
        raise ModelError(f"{source.name}: unknown output kind {source.kind!r}")
    train, check = source.encodings(suite)
    readout = fit_readout(source.kind, suite=suite, truth=truth, train_tokens=train, check_tokens=check)
    if source.kind == "frames" and source.encoding:  # lossy videos: the readout checked through the same encoding
        readout = codec_checked(readout, suite=suite, truth=truth, encoding=source.encoding)
    log.info(
        "%s: %s readout, R^2 %.3f on %d real check clips",
        source.name,
        readout.info.name,
        readout.info.r2_check,
        readout.info.n_check,
    )
    readings = read_source(
        source,
        suite=suite,
        truth=truth,
        readout=readout,
        conditions=settings.conditions,
        cache_root=cache_root,
        progress=progress,
    )
    with one_blas_thread():
        scored = score_readings(
            readings,
            score.scorer(table),
            bootstrap=settings.bootstrap,
            seed=settings.seed,
            static_limit=settings.static_limit,
        )
    return Evaluation(
        **{f.name: getattr(scored, f.name) for f in fields(scored)},
        model=source.name,
        kind=source.kind,
        suite=suite.checksum,
        suite_version=SUITE_VERSION,
        readout=readout.info,
        n_objects=suite.n_objects,
        n_speeds=suite.n_speeds,
        n_samples=source.n_samples,
        bootstrap=settings.bootstrap,
        readings=readings,
    )


def evaluate(
    models: Sequence[Any] = (),
    *,
    suite: Suite | str | Path,
    rollouts: Sequence[str | Path | RolloutsFile] = (),
    settings: EvaluateConfig | None = None,
    score: ScoreConfig | None = None,
    samples: int | None = None,
    cache_dir: str | Path | None = None,
    progress: bool = False,
) -> list[Evaluation]:
    """Evaluate world models on a suite: one :class:`Evaluation` per model, models first, then files.

    models: model objects or ``MODULE:FACTORY`` strings (see :mod:`imply.evaluate.interface`).
    rollouts: rollouts files written elsewhere (:mod:`imply.evaluate.rollouts_file`), or rollouts already read
      (a folder of generated videos: :func:`imply.evaluate.video_package.read_videos`).
    samples: sample sets asked of a stochastic model (default ``settings.samples``).
    cache_dir: keep each finished batch there, so a rerun skips it (None: no cache).
    """
    settings = settings or EvaluateConfig()
    score = score or ScoreConfig()
    if not models and not rollouts:
        raise ValueError("nothing to evaluate: give at least one model or rollouts file")
    if not isinstance(suite, Suite):
        suite = load_suite(suite)
    truth = load_truth(suite)
    table = PushTable.load(suite_table_path(suite))
    n_samples = settings.samples if samples is None else int(samples)
    sources: list[Source] = []
    for i, m in enumerate(models):
        label = m if isinstance(m, str) else f"model {i + 1}"
        model = load_model(m, suite=suite) if isinstance(m, str) else m
        sources.append(ModelSource(model, label=label, samples=n_samples))
    for path in rollouts:  # a file's path, or rollouts already read (a folder of videos)
        data = (
            path
            if isinstance(path, RolloutsFile)
            else read_rollouts_file(path, suite=suite, conditions=settings.conditions)
        )
        sources.append(FileSource(data))
    names = [src.name for src in sources]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise ModelError(f"two models are named {twice[0]!r}; give each a distinct name (its name attribute)")
    root = Path(cache_dir) if cache_dir is not None else None
    return [
        evaluate_source(
            src,
            suite=suite,
            truth=truth,
            table=table,
            settings=settings,
            score=score,
            cache_root=root,
            progress=progress,
        )
        for src in sources
    ]
