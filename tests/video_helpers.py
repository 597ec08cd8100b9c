"""Videos a model elsewhere would write for an exported suite, one per case (PNG frame folders or MP4)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from imply.evaluate.harness import make_request
from imply.evaluate.standins import oracle
from imply.evaluate.suite import load_suite
from imply.evaluate.video_package import case_list, write_mp4

CONDITIONS = ("own", "other", "none")


def write_png(path, frame):
    from PIL import Image

    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(frame).save(path)


def generate_videos(
    suite, model, folder, *, mp4: bool = False, fps: float = 10.0, skip: tuple[str, ...] = (), scale: int = 1
):
    """What a model elsewhere would write: each case's context frames, then its rollout, one video per case
    (``scale`` times the camera's size, each pixel repeated)."""
    C = suite.context_frames.shape[2]
    index = np.arange(suite.n_objects)
    for condition in CONDITIONS:
        frames = model.rollout(make_request(suite, index, condition=condition, sample=0))
        for case in case_list(suite, (condition,)):
            if case.case_id in skip:
                continue
            video = np.concatenate([suite.context_frames[case.n, case.k, :C], frames[case.n, case.k]])
            video = video.repeat(scale, axis=1).repeat(scale, axis=2)
            if mp4:
                write_mp4(folder / f"{case.case_id}.mp4", video, fps)
            else:
                for t, f in enumerate(video):
                    write_png(folder / case.case_id / f"frame_{t:03d}.png", f)


def oracle_pngs(suite_folder: Path, folder: Path) -> Path:
    """The oracle stand-in's videos of every case of the suite in ``suite_folder``, as PNG frame folders."""
    suite = load_suite(suite_folder)
    generate_videos(suite, oracle(suite), folder)
    return folder
