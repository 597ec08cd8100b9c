"""The pixel-space video model: its advection is an exact shift, sample sets are reproducible and differ, the
calibrated variant refuses to run without calibration, and a few epochs on synthetic pushes learn to move the
box further at higher speed."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import torch

from imply.models.pixel_video import PixelVideoConfig, generate, shift_right, train_pixel_video
from imply.readout import frame_diff_shift

H, W = 12, 48


def _frame(col: float) -> np.ndarray:
    f = np.full((H, W, 3), 90, np.uint8)
    c = int(round(col))
    f[4:8, c : c + 4] = (200, 40, 40)
    return f


def _split(n_objects: int, seed: int = 0) -> tuple[np.ndarray, pd.DataFrame]:
    """A clip split laid out like ``train``: 2 calibration pushes and a query per object; the box slides
    ``gain`` x 20 x speed pixels, ``gain`` a property of the object."""
    rng = np.random.default_rng(seed)
    frames, rows = [], []
    for i in range(n_objects):
        gain = rng.uniform(0.5, 1.5)
        for role, v in (("calibration_0", 0.3), ("calibration_1", 0.8), ("query", rng.uniform(0.2, 1.0))):
            start = 3.0
            d = gain * 20.0 * v
            clip = np.stack([_frame(start + d * min(1.0, t / 7)) for t in range(8)])
            frames.append(clip)
            rows.append({"object_id": f"o{i}", "role": role, "speed": v, "displacement": d / 100})
    return np.stack(frames), pd.DataFrame(rows)


def test_advection_with_a_one_hot_kernel_is_an_exact_shift():
    x = torch.rand(2, 3, H, W)
    kernel = torch.zeros(2, 10)
    kernel[0, 0], kernel[1, 7] = 1.0, 1.0
    out = shift_right(x, kernel)
    assert torch.equal(out[0], x[0])
    assert torch.equal(out[1, ..., 7:], x[1, ..., :-7]) and torch.all(out[1, ..., :7] == 0)


@pytest.fixture(scope="module")
def trained():
    frames, meta = _split(48)
    cfg = PixelVideoConfig(calibrated=False, width=8, latent=2, max_shift=32, frames=(7,), epochs=25,
                           batch_size=8, lr=1e-2, threads=1)  # fmt: skip
    return train_pixel_video(frames, meta, cfg)


def test_training_moves_the_box_further_at_higher_speed_and_sets_differ(trained):
    model, history = trained
    assert history[-1]["mse"] < history[0]["mse"]
    context = np.stack([_frame(3.0)] * 2)[:, None].repeat(3, 1)  # (2 objects, 3 speeds, H, W, 3)
    speeds = np.array([0.2, 0.5, 0.9])
    out = generate(model, context=context, speeds=speeds, sample=0)
    assert out.shape == (2, 3, 1, H, W, 3) and out.dtype == np.uint8
    shift = frame_diff_shift(context.reshape(-1, H, W, 3), out[:, :, -1].reshape(-1, H, W, 3)).reshape(2, 3)
    assert np.all(np.diff(shift[0]) > 1.0), shift  # faster pushes slide further
    # a sample set is the same each time it is asked; two sets imagine different objects
    again = generate(model, context=context, speeds=speeds, sample=3)
    assert np.array_equal(again, generate(model, context=context, speeds=speeds, sample=3))
    other = generate(model, context=context, speeds=speeds, sample=4)
    assert not np.array_equal(again, other)


def test_the_calibrated_variant_needs_the_calibration_pushes():
    frames, meta = _split(8)
    cfg = PixelVideoConfig(calibrated=True, width=8, latent=2, max_shift=32, frames=(7,), epochs=1, threads=1)
    model, _ = train_pixel_video(frames, meta, cfg)
    context = frames[meta.index[meta.role == "query"]][:, None, 0]
    with pytest.raises(ValueError, match="calibration"):
        generate(model, context=context, speeds=np.array([0.5]), sample=0)
    cal = np.stack([meta.index[meta.role == "calibration_0"], meta.index[meta.role == "calibration_1"]], 1)
    out = generate(model, context=context, speeds=np.array([0.5]), sample=0, calib_first=frames[cal, 0],
                   calib_rest=frames[cal, -1], calib_speed=np.array([0.3, 0.8]))  # fmt: skip
    assert out.shape == (8, 1, 1, H, W, 3)
