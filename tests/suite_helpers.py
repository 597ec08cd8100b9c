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


# a random (untrained) CPU encoder for 16 x 64 frames: a 1 x 4 patch grid of width 24
TINY_ENCODER_ARCH = {"patch_size": 16, "tubelet_size": 2, "embed_dim": 24, "depth": 2, "num_heads": 2}


def build_eight_frame_suite(out_dir: Path, table_path: Path, **changes) -> Path:
    """The tiny suite with the study's 8 frames per clip (what a trained predictor's layout expects)."""
    return build_suite(
        SuiteConfig.from_dict({**TINY_SUITE, **changes}),
        clips=ClipsConfig.from_dict({**TINY_SUITE_CLIPS, "frame_times": list(ClipsConfig().frame_times)}),
        scene=SceneConfig(),
        speeds=ScoreConfig(),
        table_path=table_path,
        out_dir=out_dir,
        progress=False,
    )


def write_tiny_encoder(path: Path) -> Path:
    """A random CPU encoder file (seeded) in the format ``imply study encoder pretrain`` writes."""
    import torch

    from imply.models.config import ViTConfig
    from imply.models.encoder import save_cpu_encoder
    from imply.models.vision_transformer import VisionTransformer

    torch.manual_seed(0)
    save_cpu_encoder(path, VisionTransformer(ViTConfig.from_dict(TINY_ENCODER_ARCH)), input_size=(16, 64))
    return path
