"""Clips stage: rendering, storage, the encoder's two checkpoint formats and the CPU default, readouts."""

from __future__ import annotations

import hashlib

import numpy as np
import pytest
import torch

from imply.data.clips import ClipsConfig, load_split, plan_clips, render_split, save_split
from imply.models.encoder import EncoderError, encode_clips, load_encoder, preprocess, strip_prefixes
from imply.models.vision_transformer import VisionTransformer, ViTConfig
from imply.readout import FrameDiffReadout, RidgeReadout, frame_diff_shift, load_readout, r2_log
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
SPEEDS = {"calibration_speeds": [0.3, 0.8], "query_speeds": [0.25, 0.55, 0.85]}
TINY_ARCH = {"patch_size": 16, "tubelet_size": 2, "embed_dim": 24, "depth": 2, "num_heads": 2}


@pytest.fixture(scope="module")
def tiny_cfg() -> ClipsConfig:
    return ClipsConfig.from_dict(TINY_CLIPS, SPEEDS)


@pytest.fixture(scope="module")
def rendered(tiny_cfg):
    return {s: render_split(tiny_cfg, s, SceneConfig(), progress=False) for s in ("train", "heldout_calib")}


def test_plan_layout(tiny_cfg):
    train = plan_clips(tiny_cfg, "train", SceneConfig())
    held = plan_clips(tiny_cfg, "heldout_calib", SceneConfig())
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
    again, meta2 = render_split(tiny_cfg, "heldout_calib", SceneConfig(), progress=False)
    assert np.array_equal(frames, again)
    digests = []
    for k in range(2):
        save_split(tmp_path / f"s{k}.npz", tmp_path / f"s{k}.csv", frames, meta, tiny_cfg)
        digests.append([hashlib.sha256((tmp_path / f"s{k}.{e}").read_bytes()).hexdigest() for e in ("npz", "csv")])
    assert digests[0] == digests[1]
    f2, m2 = load_split(tmp_path / "s0.npz")
    assert np.array_equal(f2, frames) and list(m2.object_id) == list(meta.object_id)


def test_config_errors():
    with pytest.raises(ValueError, match="unknown clips option"):
        ClipsConfig.from_dict({**TINY_CLIPS, "n_frames": 3}, SPEEDS)
    with pytest.raises(ValueError, match="frame_times"):
        from imply.sim.render import record_pushes

        record_pushes([0.3], [0.5], [0.3], [[0.05, 0.05, 0.03]], [0.1, 0.05])


def _frames(n=3, h=32, w=64, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (n, h, w, 3), dtype=np.uint8)


def test_official_pt_checkpoint_loads(tmp_path):
    torch.manual_seed(0)
    model = VisionTransformer(ViTConfig.from_dict(TINY_ARCH)).eval()
    state = {f"module.backbone.{k}": v for k, v in model.state_dict().items()}
    torch.save({"target_encoder": state, "epoch": 3}, tmp_path / "vitg.pt")
    enc = load_encoder(
        {
            "kind": "vjepa2_pt",
            "weights": str(tmp_path / "vitg.pt"),
            "arch": TINY_ARCH,
            "input_size": [32, 64],
            "device": "cpu",
        }
    )
    frames = _frames()
    out = enc.encode(frames)
    assert out.shape == (3, 2 * 4, 24) and enc.grid == (2, 4)
    with torch.no_grad():
        ref = model(preprocess(frames, (32, 64)))
    torch.testing.assert_close(out, ref)
    # frames are encoded one at a time: a frame's tokens do not depend on its batch
    torch.testing.assert_close(enc.encode(frames[1:2])[0], out[1], rtol=1e-4, atol=1e-5)
    # the 'encoder' key is used when there is no target encoder; a wrong architecture is refused
    torch.save({"encoder": state}, tmp_path / "enc.pt")
    enc2 = load_encoder(
        {"kind": "vjepa2_pt", "weights": str(tmp_path / "enc.pt"), "arch": TINY_ARCH, "input_size": [32, 64]}
    )
    torch.testing.assert_close(enc2.encode(frames), out)
    with pytest.raises(EncoderError, match="do not fit"):
        load_encoder({"kind": "vjepa2_pt", "weights": str(tmp_path / "enc.pt"), "arch": {**TINY_ARCH, "depth": 3}})
    with pytest.raises(EncoderError, match="not a file"):
        load_encoder({"kind": "vjepa2_pt", "weights": str(tmp_path / "missing.pt")})
    assert strip_prefixes({"module.backbone.norm.weight": 1}) == {"norm.weight": 1}


def _tiny_hf_model(tmp_path):
    transformers = pytest.importorskip("transformers")
    cfg = transformers.VJEPA2Config(
        crop_size=32, frames_per_clip=2, tubelet_size=2, patch_size=16, hidden_size=24, num_attention_heads=2,
        num_hidden_layers=2, mlp_ratio=4.0, pred_hidden_size=12, pred_num_attention_heads=2,
        pred_num_hidden_layers=1, num_pooler_layers=1,
    )  # fmt: skip
    torch.manual_seed(1)
    model = transformers.VJEPA2Model(cfg).eval()
    model.save_pretrained(tmp_path / "hf")
    return model


def test_hf_directory_loads_and_matches_our_vit(tmp_path):
    hf = _tiny_hf_model(tmp_path)
    enc = load_encoder({"kind": "vjepa2_hf", "weights": str(tmp_path / "hf"), "device": "cpu"})
    frames = _frames(h=20, w=20)  # resized to the model's 32 x 32 crop
    out = enc.encode(frames)
    assert out.shape == (3, 4, 24)
    # our ViT with the HF weights gives the same tokens: the two are the same architecture
    sd = hf.state_dict()
    ours = {"patch_embed.proj.weight": sd["encoder.embeddings.patch_embeddings.proj.weight"],
            "patch_embed.proj.bias": sd["encoder.embeddings.patch_embeddings.proj.bias"],
            "norm.weight": sd["encoder.layernorm.weight"], "norm.bias": sd["encoder.layernorm.bias"]}  # fmt: skip
    for i in range(2):
        p = f"encoder.layer.{i}."
        for a, b in (
            ("norm1", "norm1"),
            ("norm2", "norm2"),
            ("mlp.fc1", "mlp.fc1"),
            ("mlp.fc2", "mlp.fc2"),
            ("attn.proj", "attention.proj"),
        ):
            for t in ("weight", "bias"):
                ours[f"blocks.{i}.{a}.{t}"] = sd[f"{p}{b}.{t}"]
        for t in ("weight", "bias"):
            ours[f"blocks.{i}.attn.qkv.{t}"] = torch.cat(
                [sd[f"{p}attention.{n}.{t}"] for n in ("query", "key", "value")]
            )
    vit = VisionTransformer(ViTConfig.from_dict(TINY_ARCH)).eval()
    vit.load_state_dict(ours, strict=True)
    with torch.no_grad():
        ref = vit(preprocess(frames, (32, 32)))
    torch.testing.assert_close(out, ref, rtol=1e-4, atol=1e-4)


def test_hf_missing_dir_is_a_clear_error(tmp_path):
    with pytest.raises(EncoderError, match="config.json"):
        load_encoder({"kind": "vjepa2_hf", "weights": str(tmp_path)})


def test_cpu_pretrain_and_features(tmp_path, rendered):
    from imply.models.encoder import load_features, save_cpu_encoder, save_features
    from imply.models.pretrain import PretrainConfig, pretrain_encoder

    frames, meta = rendered["train"]
    flat = frames.reshape(-1, 16, 64, 3)
    cfg = PretrainConfig(steps=8, batch_size=8, warmup=2, mask_cols=(1, 2), pred_dim=16, pred_heads=2)
    model, hist = pretrain_encoder(flat, ViTConfig.from_dict(TINY_ARCH), cfg, progress=False)
    assert np.isfinite(hist["loss"]).all()
    save_cpu_encoder(tmp_path / "enc.pt", model, (16, 64))
    enc = load_encoder({"kind": "cpu", "device": "cpu"}, tmp_path / "enc.pt")
    tokens, grid = encode_clips(enc, frames, batch_size=7, progress=False)
    assert tokens.shape == (9, 4, 4, 24) and tokens.dtype == np.float16 and grid == (1, 4)
    save_features(tmp_path / "f.npz", tokens, meta.clip_id, grid, enc.name)
    back = load_features(tmp_path / "f.npz")
    assert np.array_equal(back["tokens"], tokens) and back["grid"] == (1, 4)
    # the same seed gives the same weights
    model2, _ = pretrain_encoder(flat, ViTConfig.from_dict(TINY_ARCH), cfg, progress=False)
    for a, b in zip(model.state_dict().values(), model2.state_dict().values(), strict=True):
        assert torch.equal(a, b)


def test_ridge_readout_recovers_a_linear_map(tmp_path):
    rng = np.random.default_rng(0)
    x = rng.normal(size=(400, 4, 8))
    w = rng.normal(size=32)
    log_d = x.reshape(400, -1) @ w * 0.05 - 2.5
    d = np.exp(log_d + rng.normal(scale=0.01, size=400))
    r = RidgeReadout.fit(x[:300], d[:300])
    assert r2_log(d[300:], r.predict(x[300:])) > 0.95
    r.save(tmp_path / "ridge.npz")
    back = load_readout(tmp_path / "ridge.npz")
    np.testing.assert_allclose(back.predict(x[300:]), r.predict(x[300:]))
    np.testing.assert_allclose(back.predict(x[300:].reshape(100, -1)), r.predict(x[300:]))
    with pytest.raises(ValueError, match="do not match"):
        back.predict(x[:, :2])
    # features that carry nothing read nothing
    noise = RidgeReadout.fit(rng.normal(size=(300, 4, 8)), d[:300])
    assert r2_log(d[300:], noise.predict(rng.normal(size=(100, 4, 8)))) < 0.2


def test_frame_difference_reads_a_moving_square():
    first = np.full((4, 20, 60, 3), 120, dtype=np.uint8)
    last = first.copy()
    for i, s in enumerate([0, 3, 10, 30]):
        first[i, 5:13, 4:12] = (200, 80, 50)
        last[i, 5:13, 4 + s : 12 + s] = (200, 80, 50)
    np.testing.assert_allclose(frame_diff_shift(first, last), [0, 3, 10, 30], atol=1e-9)
    clips = np.stack([first, last], axis=1)
    fd = FrameDiffReadout.fit(clips, np.array([0.001, 0.03, 0.1, 0.3]))
    np.testing.assert_allclose(fd.slope, 0.01, rtol=0.05)


def test_cli_refuses_bad_input_with_one_line(tmp_path, capsys):
    from imply.cli import main

    out = tmp_path / "x.npz"
    rc = main(["clips", "render", "--split", "bogus", "--clips-json", "{}", "--score-json", "{}",
               "--out-npz", str(out), "--out-csv", str(tmp_path / "x.csv")])  # fmt: skip
    assert rc == 2 and "--split" in capsys.readouterr().err and not out.exists()
    frames = tmp_path / "f.npz"
    np.savez(frames, frames=np.zeros((1, 2, 16, 16, 3), np.uint8), clip_id=np.zeros(1, np.int64))
    rc = main(["encoder", "encode", "--clips", str(frames), "--encoder-json", '{"kind": "vjepa2_pt", "weights": "/nope.pt"}',
               "-o", str(out)])  # fmt: skip
    err = capsys.readouterr().err
    assert rc == 2 and "encoder.weights" in err and len(err.strip().splitlines()) == 1 and not out.exists()
