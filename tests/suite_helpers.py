"""The tiny evaluation suite's settings and builder, shared by tests/evaluate (its fixture ``tiny_suite``) and its tests."""

from __future__ import annotations

from pathlib import Path

from imply.data.clips import ClipsConfig
from imply.evaluate.suite import SuiteConfig, build_suite
from imply.score import ScoreConfig
from imply.sim import SceneConfig

# 8 training and 6 held-out objects, 4 frames of 16 x 64 px: the suite in seconds
TINY_SUITE_CLIPS = {
    "seed": 2,
    "n_train_episodes": 8,
    "n_heldout_calib": 6,
    "n_heldout_nocalib": 2,
    "frame_times": [0.0, 0.05, 0.2],
    "camera": {"x_min": -0.13, "x_max": 1.15, "height": 16, "width": 64, "multisample": 4},
    "batch": 32,
}
TINY_SUITE = {"n_objects": 6, "n_readout_train": 4, "n_readout_check": 3}


def build_tiny_suite(out_dir: Path, table_path: Path, **changes) -> Path:
    """The tiny suite (the study's speeds and scene) in ``out_dir``; ``changes`` override section suite."""
    return build_suite(
        SuiteConfig.from_dict({**TINY_SUITE, **changes}),
        clips=ClipsConfig.from_dict(TINY_SUITE_CLIPS),
        scene=SceneConfig(),
        speeds=ScoreConfig(),
        table_path=table_path,
        out_dir=out_dir,
        progress=False,
    )
