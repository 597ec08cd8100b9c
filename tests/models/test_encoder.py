"""The frozen frame encoder: both released checkpoint formats, the CPU default's pretraining, cached features."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from imply.models.config import ViTConfig
from imply.models.encoder import EncoderConfig, EncoderError, encode_clips, load_encoder, strip_prefixes
from imply.models.vision_transformer import VisionTransformer, preprocess

TINY_ARCH = {"patch_size": 16, "tubelet_size": 2, "embed_dim": 24, "depth": 2, "num_heads": 2}


def load(encoder: dict, weights=None):
    """:func:`load_encoder` of config section ``encoder`` given as a mapping."""
    return load_encoder(EncoderConfig.from_dict(encoder), weights)


def _frames(n=3, h=32, w=64, seed=0):
    return np.random.default_rng(seed).integers(0, 256, (n, h, w, 3), dtype=np.uint8)


def test_official_pt_checkpoint_loads(tmp_path):
    torch.manual_seed(0)
    model = VisionTransformer(ViTConfig.from_dict(TINY_ARCH)).eval()
    state = {f"module.backbone.{k}": v for k, v in model.state_dict().items()}
    torch.save({"target_encoder": state, "epoch": 3}, tmp_path / "vitg.pt")
    enc = load(
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
    enc2 = load({"kind": "vjepa2_pt", "weights": str(tmp_path / "enc.pt"), "arch": TINY_ARCH, "input_size": [32, 64]})
    torch.testing.assert_close(enc2.encode(frames), out)
    with pytest.raises(EncoderError, match="do not fit"):
        load({"kind": "vjepa2_pt", "weights": str(tmp_path / "enc.pt"), "arch": {**TINY_ARCH, "depth": 3}})
    with pytest.raises(EncoderError, match="not a file"):
        load({"kind": "vjepa2_pt", "weights": str(tmp_path / "missing.pt")})
    assert strip_prefixes({"module.backbone.norm.weight": 1}) == {"norm.weight": 1}


def _tiny_hf_model(tmp_path):
    transformers = pytest.importorskip("transformers")
    cfg = transformers.VJEPA2Config(
        crop_size=32,
        frames_per_clip=2,
        tubelet_size=2,
        patch_size=16,
        hidden_size=24,
        num_attention_heads=2,
        num_hidden_layers=2,
        mlp_ratio=4.0,
        pred_hidden_size=12,
        pred_num_attention_heads=2,
        pred_num_hidden_layers=1,
        num_pooler_layers=1,
    )
    torch.manual_seed(1)
    model = transformers.VJEPA2Model(cfg).eval()
    model.save_pretrained(tmp_path / "hf")
    return model


def test_hf_directory_loads_and_matches_our_vit(tmp_path):
    hf = _tiny_hf_model(tmp_path)
    enc = load({"kind": "vjepa2_hf", "weights": str(tmp_path / "hf"), "device": "cpu"})
    frames = _frames(h=20, w=20)  # resized to the model's 32 x 32 crop
    out = enc.encode(frames)
    assert out.shape == (3, 4, 24)
    # our ViT with the HF weights gives the same tokens: the two are the same architecture
    sd = hf.state_dict()
    ours = {
        "patch_embed.proj.weight": sd["encoder.embeddings.patch_embeddings.proj.weight"],
        "patch_embed.proj.bias": sd["encoder.embeddings.patch_embeddings.proj.bias"],
        "norm.weight": sd["encoder.layernorm.weight"],
        "norm.bias": sd["encoder.layernorm.bias"],
    }
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
        load({"kind": "vjepa2_hf", "weights": str(tmp_path)})


def test_cpu_pretrain_and_features(tmp_path):
    from imply.models.encoder import load_features, save_cpu_encoder, save_features
    from imply.models.pretrain import PretrainConfig, pretrain_encoder

    frames = np.random.default_rng(1).integers(0, 256, (9, 4, 16, 64, 3), dtype=np.uint8)
    flat = frames.reshape(-1, 16, 64, 3)
    cfg = PretrainConfig(steps=8, batch_size=8, warmup=2, mask_cols=(1, 2), pred_dim=16, pred_heads=2)
    model, hist = pretrain_encoder(flat, ViTConfig.from_dict(TINY_ARCH), cfg, progress=False)
    assert np.isfinite(hist["loss"]).all()
    save_cpu_encoder(tmp_path / "enc.pt", model, input_size=(16, 64))
    enc = load({"kind": "cpu", "device": "cpu"}, tmp_path / "enc.pt")
    tokens, grid = encode_clips(enc, frames, batch_size=7, progress=False)
    assert tokens.shape == (9, 4, 4, 24) and tokens.dtype == np.float16 and grid == (1, 4)
    save_features(tmp_path / "f.npz", tokens, clip_id=np.arange(9), grid=grid, name=enc.name)
    back = load_features(tmp_path / "f.npz")
    assert np.array_equal(back["tokens"], tokens) and back["grid"] == (1, 4)
    # the same seed gives the same weights
    model2, _ = pretrain_encoder(flat, ViTConfig.from_dict(TINY_ARCH), cfg, progress=False)
    for a, b in zip(model.state_dict().values(), model2.state_dict().values(), strict=True):
        assert torch.equal(a, b)


def test_pooled_features_are_the_one_pooling_of_each_frames_tokens(tmp_path):
    from imply.models.features import pool_tokens

    torch.manual_seed(0)
    model = VisionTransformer(ViTConfig.from_dict(TINY_ARCH)).eval()
    torch.save({"target_encoder": model.state_dict()}, tmp_path / "vit.pt")
    enc = load({"kind": "vjepa2_pt", "weights": str(tmp_path / "vit.pt"), "arch": TINY_ARCH, "input_size": [32, 64]})
    clips = np.random.default_rng(2).integers(0, 256, (3, 2, 32, 64, 3), dtype=np.uint8)
    tokens, grid = encode_clips(enc, clips, batch_size=4, pool_grid=(1, 2), progress=False)
    assert grid == (1, 2) and tokens.shape == (3, 2, 2, 24) and tokens.dtype == np.float16
    each = enc.encode(clips.reshape(6, 32, 64, 3)).numpy()  # (6, 2*4, 24) on the 2 x 4 grid
    expect = pool_tokens(each[:, None], (2, 4), (1, 2))[:, 0].astype(np.float16).reshape(3, 2, 2, 24)
    assert np.allclose(tokens.astype(np.float32), expect.astype(np.float32), atol=2e-3)
    # the right pooled token is the mean of the right half of the grid
    right = each.reshape(6, 2, 4, 24)[:, :, 2:].mean(axis=(1, 2)).reshape(3, 2, 24)
    assert np.allclose(tokens[:, :, 1].astype(np.float32), right, atol=2e-3)
    with pytest.raises(ValueError, match="does not divide"):
        encode_clips(enc, clips, pool_grid=(1, 3), progress=False)
