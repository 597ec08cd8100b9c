"""The pixel-space video model: its advection is an exact shift (and keeps the box's centroid at sub-pixel
shifts), its table carries no red, sample sets are reproducible and differ, the calibrated variant refuses to run
without calibration, a few epochs on synthetic pushes learn to move the box further at higher speed, and a saved
model runs behind imply evaluate's interface."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import torch

from imply.evaluate.interface import check_model
from imply.models.pixel_video import (
    PixelVideoConfig,
    box_column,
    generate,
    load_pixel_video,
    save_pixel_video,
    to_float,
    train_pixel_video,
    trained_pixel_video,
    translate,
)
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


def test_advection_is_an_exact_shift_and_keeps_the_centroid_between_pixels():
    x = torch.rand(2, 3, H, W)
    out = translate(x, torch.tensor([0.0, 7.0]))
    assert torch.allclose(out[0], x[0], atol=1e-6)
    assert torch.allclose(out[1, ..., 7:], x[1, ..., :-7], atol=1e-6) and torch.all(out[1, ..., :7].abs() < 1e-6)
    box = torch.zeros(3, 1, H, W)
    box[..., 4:8, 10:14] = 1.0
    moved = translate(box, torch.tensor([0.0, 2.25, 5.5]))[:, 0].sum(-2)  # (3, W) column mass
    centroid = (moved * torch.arange(W)).sum(-1) / moved.sum(-1)
    assert torch.allclose(centroid - 11.5, torch.tensor([0.0, 2.25, 5.5]), atol=1e-4)
    # the keypoint reads whole-pixel slides of a drawn box exactly
    frames = to_float(np.stack([_frame(10.0), _frame(13.0), _frame(21.0)]))
    assert torch.allclose(box_column(frames) - box_column(frames[:1]), torch.tensor([0.0, 3.0, 11.0]))


@pytest.fixture(scope="module")
def trained():
    frames, meta = _split(48)
    cfg = PixelVideoConfig(width=8, latent=2, frames=(7,), epochs=25, batch_size=8, lr=1e-2)
    return train_pixel_video(frames, meta, cfg, calibrated=False, threads=1, progress=False)


def test_training_moves_the_box_further_at_higher_speed_and_sets_differ(trained):
    model, history = trained
    assert history[-1]["nll"] < history[0]["nll"] and history[-1]["pixels"] < history[0]["pixels"]
    # the table it learned carries no red: the box is the only thing the frame readout sees
    table = model.table(0)
    assert torch.all(table[0] <= table[1])
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
    cfg = PixelVideoConfig(width=8, latent=2, frames=(7,), epochs=1)
    model, _ = train_pixel_video(frames, meta, cfg, calibrated=True, threads=1, progress=False)
    context = frames[meta.index[meta.role == "query"]][:, None, 0]
    with pytest.raises(ValueError, match="calibration"):
        generate(model, context=context, speeds=np.array([0.5]), sample=0)
    cal = np.stack([meta.index[meta.role == "calibration_0"], meta.index[meta.role == "calibration_1"]], 1)
    out = generate(
        model,
        context=context,
        speeds=np.array([0.5]),
        sample=0,
        calib_first=frames[cal, 0],
        calib_rest=frames[cal, -1],
        calib_speed=np.array([0.3, 0.8]),
    )
    assert out.shape == (8, 1, 1, H, W, 3)


def test_a_saved_model_runs_behind_the_evaluate_interface(trained, tmp_path):
    model, history = trained
    path = tmp_path / "pixel.pt"
    save_pixel_video(path, model, history)
    loaded, again = load_pixel_video(path)
    assert again == history
    world = trained_pixel_video(checkpoint=str(path), batch_size="4")
    check_model(world, "pixel")
    assert world.kind == "frames" and world.stochastic and world.name == "pixel_nocalib"

    class Request:  # the fields of imply.evaluate.interface.RolloutRequest that the model reads
        object_ids = ("a", "b")
        condition = "none"
        query_speeds = np.array([0.3, 0.7])
        context_frames = np.stack([_frame(3.0)] * 4).reshape(2, 2, 1, H, W, 3)
        calibration_frames = calibration_speeds = None

    for sample in (0, 2):
        Request.sample = sample
        out = world.rollout(Request)
        assert out.shape == (2, 2, 1, H, W, 3)
        # an object's sample set does not depend on the batch it comes in
        Request.object_ids, Request.context_frames = ("b",), Request.context_frames[1:]
        assert np.array_equal(world.rollout(Request)[0], out[1])
        Request.object_ids, Request.context_frames = ("a", "b"), np.concatenate([Request.context_frames] * 2)
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    with pytest.raises(ValueError, match="not a pixel video checkpoint"):
        load_pixel_video(tmp_path / "junk.pt")
