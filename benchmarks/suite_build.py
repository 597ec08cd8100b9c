"""Benchmark of the evaluation suite's build, against rendering the same pushes as a clip split in the same process.

Run: MUJOCO_GL=egl python benchmarks/suite_build.py [--config config.yaml] [--threads 2] [--table TABLE]

Builds the suite of ``--config`` (sections suite, clips, scene, score) in a temporary
folder with ``imply.evaluate.suite.build_suite`` and prints its seconds, pushes and
frames drawn; then renders a training split of as many pushes (every frame of every clip,
as ``imply study clips render`` does) with ``imply.data.clips.render_split``, and prints the
ratio of the two. The issue's target: the default suite in at most 2 minutes on 2 cores.
``--table`` defaults to results/table/table.npz (the suite only copies it).
Benchmarks measure; they assert nothing.
"""

from __future__ import annotations

import argparse
import logging
import tempfile
import time
from pathlib import Path

import yaml

from imply.data.clips import ClipsConfig, render_split
from imply.evaluate.suite import SuiteConfig, build_suite, load_suite
from imply.score import ScoreConfig
from imply.sim import SceneConfig


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--config", default="config.yaml")
    parser.add_argument("--threads", type=int, default=2)
    parser.add_argument("--table", default="results/table/table.npz")
    parser.add_argument("--no-baseline", action="store_true", help="time the suite only")
    args = parser.parse_args()
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")
    with open(args.config) as fh:
        cfg = yaml.safe_load(fh)
    suite_cfg = SuiteConfig.from_dict(cfg["suite"])
    clips = ClipsConfig.from_dict(cfg["clips"])
    scene = SceneConfig.from_dict(cfg["scene"])
    speeds = ScoreConfig.from_dict(cfg["score"])

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        folder = build_suite(
            suite_cfg,
            clips=clips,
            scene=scene,
            speeds=speeds,
            table_path=Path(args.table),
            out_dir=Path(tmp) / "suite",
            nthread=args.threads,
            progress=False,
        )
        suite_s = time.perf_counter() - t0
        sizes = load_suite(folder).manifest["sizes"]
    n, k, c, t, m, mc = (sizes[key] for key in ("N", "K", "C", "T", "M", "M_c"))
    pushes = n * (2 + k) + m + mc
    frames = n * (2 * t + k * (c + 1)) + 2 * (m + mc)
    print(
        f"suite: N {n}, K {k}, C {c}, T {t}, M {m}, M_c {mc}, {sizes['H']} x {sizes['W']} px on {args.threads} "
        f"threads: {suite_s:.1f} s, {pushes} pushes ({pushes / suite_s:.0f}/s), {frames} frames drawn "
        f"({frames / suite_s:.0f}/s)"
    )
    if args.no_baseline:
        return
    # baseline: a training split of as many pushes (3 a object), every frame drawn, simulated the same way
    same_size = clips.replace(n_train_episodes=-(-pushes // 3))
    t0 = time.perf_counter()
    base_frames, meta = render_split(
        same_size, "train", scene=scene, speeds=speeds, nthread=args.threads, progress=False
    )
    base_s = time.perf_counter() - t0
    print(
        f"baseline render_split: {len(meta)} clips, {base_frames.shape[0] * base_frames.shape[1]} frames in "
        f"{base_s:.1f} s; suite / baseline time {suite_s / base_s:.2f}"
    )


if __name__ == "__main__":
    main()
