"""The cost of ``imply evaluate`` itself: rollouts per second with models that take no time.

Trivial models of each output kind (displacements: a constant; frames: the context frame
returned as the rest frame; latents: a fixed projection of the context frame), asked as
stochastic models for S sample sets per object on a suite, so that the harness's own
work (requests, output checks, readout, scoring, bootstrap intervals, report) is all
that is timed. The baseline, run in the same process, is the scorer alone on the same
number of sets (:meth:`imply.score.Scorer.score`): the one step no evaluation can skip.

    python benchmarks/evaluate_harness.py --suite results/suite [--samples 16]

Prints per kind: rollouts, seconds, rollouts/s for ``evaluate()`` and for ``evaluate()``
plus ``write_report``, the ratio of the harness's time to the scorer's, and what the
harness would add to a model that takes 5 ms per rollout.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from imply.evaluate.config import EvaluateConfig
from imply.evaluate.harness import evaluate
from imply.evaluate.report import write_report
from imply.evaluate.suite import load_suite, suite_table_path
from imply.score import ScoreConfig, one_blas_thread
from imply.table import PushTable

MODEL_MS = 5.0  # the yardstick: a model taking 5 ms per rollout


class ConstantSlides:
    kind = "displacements"
    name = "constant slides"
    stochastic = True
    batch_size = 300

    def rollout(self, request):
        return np.full((len(request), len(request.query_speeds)), 0.05)


class StillFrames:
    kind = "frames"
    name = "still frames"
    stochastic = True
    batch_size = 300

    def rollout(self, request):
        return request.context_frames[:, :, :1]


class ProjectedFrames:
    kind = "latents"
    name = "projected frames"
    stochastic = True
    batch_size = 300

    def __init__(self, frame_shape: tuple[int, int, int]) -> None:
        h, w, c = frame_shape
        self.projection = np.random.default_rng(0).standard_normal((h * w * c // 16, 32)).astype(np.float32)

    def encode(self, frames):
        f = np.asarray(frames, dtype=np.float32)[:, ::4, ::4]
        return f.reshape(len(f), -1) @ self.projection[: f[0].size] / 255.0

    def rollout(self, request):
        first = request.context_frames[:, :, 0]
        b, k = first.shape[:2]
        return self.encode(first.reshape(b * k, *first.shape[2:])).reshape(b, k, -1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", default="results/suite")
    parser.add_argument("--samples", type=int, default=16)
    args = parser.parse_args()
    suite = load_suite(args.suite)
    settings = EvaluateConfig(samples=args.samples)
    n_sets = len(settings.conditions) * args.samples * suite.n_objects
    n_rollouts = n_sets * suite.n_speeds

    scorer = ScoreConfig().scorer(PushTable.load(suite_table_path(suite)))
    d = np.exp(np.random.default_rng(1).normal(-2.7, 0.6, (n_sets, suite.n_speeds)))
    calib = np.tile(suite.calibration_displacement, (n_sets // suite.n_objects, 1))
    with one_blas_thread():
        scorer.score(suite.query_speeds, d[:10], suite.calibration_speeds, calib[:10])  # warm the caches
        t0 = time.perf_counter()
        scorer.score(suite.query_speeds, d, suite.calibration_speeds, calib)
        t_score = time.perf_counter() - t0
    print(
        f"suite: {suite.n_objects} objects x {suite.n_speeds} speeds x {len(settings.conditions)} conditions "
        f"x {args.samples} sample sets = {n_rollouts} rollouts"
    )
    print(f"baseline, the scorer alone on {n_sets} sets: {t_score:.2f} s ({n_rollouts / t_score:,.0f} rollouts/s)")
    print(
        f"{'kind':<14} {'evaluate s':>10} {'rollouts/s':>11} {'+report s':>10} {'rollouts/s':>11} "
        f"{'x scorer':>9} {'adds to 5 ms':>12}"
    )
    for model in (ConstantSlides(), StillFrames(), ProjectedFrames(suite.frame_shape)):
        t0 = time.perf_counter()
        (ev,) = evaluate([model], suite=suite, settings=settings)
        t_eval = time.perf_counter() - t0
        with tempfile.TemporaryDirectory() as tmp:
            write_report([ev], Path(tmp) / "report")
        t_all = time.perf_counter() - t0
        added = (t_all / n_rollouts) * 1e3 / MODEL_MS
        print(
            f"{model.kind:<14} {t_eval:>10.2f} {n_rollouts / t_eval:>11,.0f} {t_all:>10.2f} "
            f"{n_rollouts / t_all:>11,.0f} {t_eval / t_score:>9.1f} {added:>11.1%}"
        )


if __name__ == "__main__":
    main()
