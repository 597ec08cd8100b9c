"""Rendered push clips: the plan of a split, rendering, byte-stable storage, settings."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest

from imply.data.clips import ClipsConfig, load_clips, plan_clips, render_split, save_split
from imply.readout import frame_diff_shift
from imply.score import ScoreConfig
from imply.sim import SceneConfig, simulate_pushes
from imply.sim.render import CameraConfig

TINY_CLIPS = {
    "seed": 3,
    "n_train_episodes": 3,
    "n_heldout_calib": 1,
    "n_heldout_nocalib": 1,
    "n_pretrain_episodes": 1,
    "frame_times": [0.0, 0.05, 0.2],
    "camera": {"x_min": -0.13, "x_max": 1.15, "height": 16, "width": 64, "multisample": 4},
    "batch": 4,
}
SPEEDS = ScoreConfig.from_dict({"calibration_speeds": [0.3, 0.8], "query_speeds": [0.25, 0.55, 0.85]})


@pytest.fixture(scope="module")
def tiny_cfg() -> ClipsConfig:
    return ClipsConfig.from_dict(TINY_CLIPS)


@pytest.fixture(scope="module")
def rendered(tiny_cfg):
    return {
        s: render_split(tiny_cfg, s, scene=SceneConfig(), speeds=SPEEDS, progress=False)
        for s in ("train", "heldout_calib")
    }


def test_plan_layout(tiny_cfg):
    train = plan_clips(tiny_cfg, "train", scene=SceneConfig(), speeds=SPEEDS)
    held = plan_clips(tiny_cfg, "heldout_calib", scene=SceneConfig(), speeds=SPEEDS)
    assert list(train["role"][:3]) == ["calibration_0", "calibration_1", "query"]
    assert len(train) == 9 and len(held) == 2 + 3
    assert list(held["speed"]) == [0.3, 0.8, 0.25, 0.55, 0.85]
    assert list(held["speed_index"]) == [-1, -1, 0, 1, 2]
    # train query speeds are drawn, within the configured range
    q = train[train.role == "query"]["speed"]
    assert q.between(0.15, 1.05).all() and q.nunique() == 3
    # objects of different splits differ
    assert not set(train.object_id) & set(held.object_id)
    assert train.mass.iloc[0] != held.mass.iloc[0]


def test_render_shapes_truth_and_motion(rendered):
    frames, meta = rendered["heldout_calib"]
    assert frames.shape == (5, 4, 16, 64, 3) and frames.dtype == np.uint8
    assert list(meta["clip_id"]) == list(range(5))
    for col in [
        "object_id",
        "role",
        "speed",
        "displacement",
        "mass",
        "friction",
        "size_x",
        "size_y",
        "size_z",
        "t0",
        "t3",
    ]:
        assert col in meta.columns
    # the stored truth is the simulator's displacement for the same pushes
    ref = simulate_pushes(
        meta.speed.to_numpy(),
        meta.mass.to_numpy(),
        meta.friction.to_numpy(),
        meta[["size_x", "size_y", "size_z"]].to_numpy(),
        nthread=1,
    )
    np.testing.assert_allclose(meta.displacement, ref.displacement, atol=2e-5)
    assert (meta.ok == 1).all()
    # the last frame is the rest state and the box has moved to the right by about its displacement
    assert np.allclose(meta.t3, meta.stop_time)
    mpp = CameraConfig.from_dict(TINY_CLIPS["camera"]).metres_per_pixel
    shift = frame_diff_shift(frames[:, 0], frames[:, -1]) * mpp
    np.testing.assert_allclose(shift, meta.displacement, atol=mpp)  # within a pixel at this tiny size
    # faster query pushes slide farther
    q = meta[meta.role == "query"].displacement.to_numpy()
    assert np.all(np.diff(q) > 0)


def test_render_is_deterministic_and_storage_byte_stable(tiny_cfg, rendered, tmp_path):
    frames, meta = rendered["heldout_calib"]
    again, meta2 = render_split(tiny_cfg, "heldout_calib", scene=SceneConfig(), speeds=SPEEDS, progress=False)
    assert np.array_equal(frames, again)
    digests = []
    for k in range(2):
        save_split(tmp_path / f"s{k}.npz", tmp_path / f"s{k}.csv", frames=frames, meta=meta, cfg=tiny_cfg)
        digests.append([hashlib.sha256((tmp_path / f"s{k}.{e}").read_bytes()).hexdigest() for e in ("npz", "csv")])
    assert digests[0] == digests[1]
    f2, m2 = load_clips(tmp_path / "s0.npz")
    assert np.array_equal(f2, frames) and list(m2.object_id) == list(meta.object_id)


def test_config_errors():
    with pytest.raises(ValueError, match="unknown clips option"):
        ClipsConfig.from_dict({**TINY_CLIPS, "n_frames": 3}, "clips")
    with pytest.raises(ValueError, match="frame_times"):
        from imply.sim.render import record_pushes

        record_pushes([0.3], [0.5], [0.3], [[0.05, 0.05, 0.03]], [0.1, 0.05])


def test_cli_refuses_bad_input_with_one_line(tmp_path, capsys):
    from imply.cli import main

    out = tmp_path / "x.npz"
    rc = main(
        ["study", "clips", "render", "--split", "bogus", "--clips-json", "{}", "--score-json", "{}", "-o", str(out)]
    )
    assert rc == 2 and "--split" in capsys.readouterr().err and not out.exists()
    frames = tmp_path / "f.npz"
    np.savez(frames, frames=np.zeros((1, 2, 16, 16, 3), np.uint8), clip_id=np.zeros(1, np.int64))
    rc = main(
        [
            "study",
            "encoder",
            "encode",
            "--clips",
            str(frames),
            "--encoder-json",
            '{"kind": "vjepa2_pt", "weights": "/nope.pt"}',
            "-o",
            str(out),
        ]
    )
    err = capsys.readouterr().err
    assert rc == 2 and "encoder.weights" in err and len(err.strip().splitlines()) == 1 and not out.exists()
