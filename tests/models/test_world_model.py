"""The trained predictor behind ``imply evaluate``: its rollouts equal the feature path's, and it loads by spec."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import torch

from imply.evaluate.harness import make_request
from imply.evaluate.interface import ModelError, load_model, parse_model_spec
from imply.evaluate.suite import load_suite
from imply.models.config import Layout, PredictorPreset
from imply.models.features import FeatureSplit
from imply.models.rollout import final_tokens
from imply.models.sequences import build_sequences
from imply.models.world_model import trained_predictor


@pytest.fixture(scope="module")
def files(tiny_table_path, tmp_path_factory):
    """(suite folder, encoder file, calibrated model file, context-free model file): 8-frame clips, like the study's."""
    from imply.models.ac_predictor import ACPredictor
    from suite_helpers import build_eight_frame_suite, write_tiny_encoder

    root = tmp_path_factory.mktemp("world_model")
    suite = build_eight_frame_suite(root / "suite", tiny_table_path, n_objects=4, n_readout_train=4)
    write_tiny_encoder(root / "encoder.pt")
    models = {}
    for variant, calib in (("calib", True), ("nocalib", False)):
        layout = Layout(calib=calib)
        cfg = PredictorPreset(width=32, depth=1, heads=2, mlp_ratio=2.0).predictor(
            embed_dim=24, grid=(1, 2), max_steps=layout.n_steps
        )
        torch.manual_seed(1)
        predictor = ACPredictor(cfg)
        models[variant] = root / variant / "seed0" / "model.pt"
        models[variant].parent.mkdir(parents=True)
        torch.save(
            {
                "predictor": cfg.to_dict(),
                "layout": layout.to_dict(),
                "token_grid": [1, 2],
                "model": predictor.state_dict(),
            },
            models[variant],
        )
    return suite, root / "encoder.pt", models["calib"], models["nocalib"]


def _feature_path_tokens(model, suite, index: np.ndarray, *, condition: str) -> np.ndarray:
    """The same rollouts through the training code's path: cached tokens of whole clips, build_sequences, final_tokens."""
    s = load_suite(suite)
    n, k = len(index), len(s.query_speeds)
    frames = s.context_frames.shape[-3:]
    # clip rows: each object's 2 calibration clips, then its K query clips (context frame, rest unknown: zeros)
    clip_frames, speeds = [], []
    for i in index:
        for j in range(2):
            clip_frames.append(s.calibration_frames[i, j])
            speeds.append(s.calibration_speeds[j])
        for q in range(k):
            clip = np.zeros((8, *frames), np.uint8)
            clip[0] = s.context_frames[i, q, 0]
            clip_frames.append(clip)
            speeds.append(s.query_speeds[q])
    clip_frames = np.stack(clip_frames)
    tokens = model.encode(clip_frames.reshape(-1, *frames)).reshape(len(clip_frames), 8, 2, 24)
    meta = pd.DataFrame({"speed": speeds, **{f"t{j}": t for j, t in enumerate(s.frame_times)}})
    split = FeatureSplit(tokens=tokens, meta=meta, grid=(1, 2))
    per = 2 + k
    calib_rows = np.arange(n)[:, None] * per + np.arange(2)[None, :]
    if condition == "other":
        partner = np.array([np.flatnonzero(index == p)[0] for p in s.partner[index]])
        calib_rows = calib_rows[partner]
    query = (np.arange(n)[:, None] * per + 2 + np.arange(k)[None, :]).reshape(-1)
    layout = model.layout if condition != "none" else model.layout.without_calibration()
    seqs = build_sequences(
        split, layout, query_clip=query, calib_clips=np.repeat(calib_rows, k, axis=0) if layout.calib else None
    )
    return final_tokens(model.predictor, seqs, batch_size=64).reshape(n, k, 2, 24)


@pytest.mark.parametrize("condition", ["own", "other", "none"])
def test_rollouts_equal_the_feature_path(files, condition):
    suite_dir, encoder, calib, _ = files
    model = trained_predictor(checkpoint=calib, encoder=encoder)
    suite = load_suite(suite_dir)
    index = np.arange(len(suite.object_ids))  # every object, so each partner is in the batch
    got = model.rollout(make_request(suite, index, condition=condition, sample=0))
    want = _feature_path_tokens(model, suite_dir, index, condition=condition)
    assert got.shape == (len(index), 5, 2, 24)
    assert np.allclose(got, want, atol=1e-5)


def test_the_calibration_shown_changes_the_calibrated_model_only(files):
    suite_dir, encoder, calib, nocalib = files
    suite = load_suite(suite_dir)
    index = np.arange(len(suite.object_ids))
    for path, changes in ((calib, True), (nocalib, False)):
        model = trained_predictor(checkpoint=path, encoder=encoder)
        own, other, none = (
            model.rollout(make_request(suite, index, condition=c, sample=0)) for c in ("own", "other", "none")
        )
        assert not np.allclose(own, other) if changes else np.array_equal(own, other)
        assert not np.allclose(own, none) if changes else np.array_equal(own, none)


def test_loaded_by_spec_with_options(files):
    suite_dir, encoder, calib, _ = files
    spec = f"imply.models.world_model:trained_predictor,checkpoint={calib},encoder={encoder},batch_size=3"
    model = load_model(spec, suite=load_suite(suite_dir))
    assert model.kind == "latents" and model.batch_size == 3 and model.name == "calib_seed0"
    with pytest.raises(ModelError, match="no option 'colour'"):
        load_model(spec + ",colour=red")
    with pytest.raises(ModelError, match="no such encoder file"):
        load_model(f"imply.models.world_model:trained_predictor,checkpoint={calib},encoder=/nonexistent.pt")


def test_model_spec_parsing():
    assert parse_model_spec("m.py:build") == ("m.py", "build", {})
    assert parse_model_spec("pkg.mod:f,a=1,b=x=y") == ("pkg.mod", "f", {"a": "1", "b": "x=y"})
    for bad, message in (
        ("m.py", "MODULE:FACTORY"),
        ("m:f,a", "not KEY=VALUE"),
        ("m:f,a=1,a=2", "twice"),
        ("m:f,suite=x", "reserved"),
    ):
        with pytest.raises(ModelError, match=message):
            parse_model_spec(bad)
