"""The file door of ``imply evaluate`` measured: the stand-ins through H.264 MP4 against in process, and read speed.

For each size (the suite's camera, and 256 x 256 by default), the four stand-ins'
rollouts (:mod:`imply.evaluate.standins`, drawn at the suite's camera, each pixel
repeated up to the size) are written as one MP4 per case exactly as ``imply suite export``
names them, read back with :func:`imply.evaluate.video_package.read_videos` and scored;
the known answers (:func:`imply.study.section4.through_evaluate.known_answers`: the oracle's
anchored disagreement against the readout's error, the object-blind model's AUROCs) are
printed beside the in-process ones, with the readout's check through the same codec. It
also times reading the folders (videos per second) and the whole scoring of one
stand-in both ways, in the same process, and prints the ratios.

Run: python benchmarks/video_door.py --suite results/suite [--sizes 0,256] [--out /tmp/video-door]
(0 stands for the suite's own camera size).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from imply.evaluate.config import EvaluateConfig
from imply.evaluate.harness import evaluate, make_request
from imply.evaluate.standins import STANDINS
from imply.evaluate.suite import load_suite
from imply.evaluate.video_package import case_list, read_videos, write_mp4
from imply.study.section4.through_evaluate import known_answers

CONDITIONS = ("own", "other", "none")


def write_standin(suite, model, folder: Path, scale_to: tuple[int, int] | None, fps: float = 10.0) -> int:
    """Every case of ``model`` as an MP4 (context frames, then its rollout), at ``scale_to`` (None: the camera)."""
    folder.mkdir(parents=True, exist_ok=True)
    C = suite.context_frames.shape[2]
    H, W = suite.frame_shape[:2]
    ry, rx = (1, 1) if scale_to is None else (scale_to[0] // H, scale_to[1] // W)
    n = 0
    index = np.arange(suite.n_objects)
    for condition in CONDITIONS:
        frames = model.rollout(make_request(suite, index, condition=condition, sample=0))
        for case in case_list(suite, (condition,)):
            video = np.concatenate([suite.context_frames[case.n, case.k, :C], frames[case.n, case.k]])
            video = video.repeat(ry, axis=1).repeat(rx, axis=2)
            write_mp4(folder / f"{case.case_id}.mp4", video, fps)
            n += 1
    return n


def _line(name: str, ka: dict) -> str:
    s = ka["standins"]
    text = (
        f"{name:28s} oracle anchored {s['oracle']['anchored']:.3f} (readout error {ka['readout']['error_check']:.3f})"
    )
    for other in (k for k in s if k != "oracle" and "auroc_anchored" in s[k]):
        text += f"; {other} AUROC anchored {s[other]['auroc_anchored']:.2f}, self {s[other]['auroc_self']:.2f}"
    return text


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", type=Path, default=Path("results/suite"))
    ap.add_argument(
        "--sizes",
        default="0,256",
        help="square sizes to write the videos at (0: the suite's camera; "
        "each a whole multiple of the camera's height and width)",
    )
    ap.add_argument("--out", type=Path, default=Path("/tmp/video-door"))
    ap.add_argument("--bootstrap", type=int, default=200)
    ap.add_argument("--standins", default="oracle,jitter,blind,collapse", help="stand-ins to write, in this order")
    args = ap.parse_args()
    suite = load_suite(args.suite)
    settings = EvaluateConfig(bootstrap=args.bootstrap)
    models = [STANDINS[name](suite) for name in args.standins.split(",")]
    t0 = time.perf_counter()
    direct = evaluate(models, suite=suite, settings=settings)
    t_direct = time.perf_counter() - t0
    print(
        f"suite {suite.checksum[:12]}: {suite.n_objects} objects, camera {suite.frame_shape[1]}x"
        f"{suite.frame_shape[0]}; in process: {len(models)} stand-ins scored in {t_direct:.1f} s"
    )
    print(_line("in process", known_answers(direct)))
    for size in (int(x) for x in args.sizes.split(",")):
        shape = None if size == 0 else (size, size)
        label = "camera" if shape is None else f"{size}x{size}"
        folders = []
        for m in models:
            folder = args.out / label / m.name
            if not folder.is_dir():
                write_standin(suite, m, folder, shape)
            folders.append(folder)
        t0 = time.perf_counter()
        read = [read_videos(f, suite, CONDITIONS) for f in folders]
        t_read = time.perf_counter() - t0
        n_videos = sum(len(list(f.glob("*.mp4"))) for f in folders)
        t0 = time.perf_counter()
        from_files = evaluate(suite=suite, rollouts=read, settings=settings)
        t_score = time.perf_counter() - t0
        ka = known_answers(from_files)
        oracle = next(e for e in from_files if e.model == "oracle")
        print(
            f"{label}: {n_videos} MP4s read in {t_read:.1f} s ({n_videos / t_read:.0f} videos/s); scored in "
            f"{t_score:.1f} s; read + score / in process {(t_read + t_score) / t_direct:.2f}x"
        )
        print(_line(f"through H.264 at {label}", ka))
        print(
            f"{'':28s} readout through the codec ({oracle.readout.encoding}): R^2 {oracle.readout.r2_codec:.3f}, "
            f"error {oracle.readout.error_codec:.3f} (lossless: R^2 {oracle.readout.r2_check:.3f}, error "
            f"{oracle.readout.error_check:.3f})"
        )


if __name__ == "__main__":
    main()
