"""Predictor inputs: query frames of a layout, frame states, pooled tokens, every push as a query, the residual output."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from imply.models.ac_predictor import ACPredictor
from imply.models.config import Layout, PredictorConfig
from imply.models.examples import training_objects, training_sequences
from imply.models.features import load_feature_split, pool_tokens
from synthetic_features import synth_split

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def split(tmp_path_factory):
    d = tmp_path_factory.mktemp("synth")
    return load_feature_split(*synth_split(d, "train", 20, False, 1, grid=(2, 4), dim=6))


def test_layout_query_frames_set_the_steps():
    layout = Layout(calib=True, query_context=1, query_frames=(0, 1, 4, 7))
    assert layout.n_steps == 6 + 4 and layout.n_context == 6 + 1
    assert layout.without_calibration().n_steps == 4 and layout.without_calibration().query_frames == (0, 1, 4, 7)
    assert Layout(calib=False, query_frames=None).n_steps == 8
    for bad in ((0, 1, 4), (0, 4, 1, 7), (1, 1, 7)):
        with pytest.raises(ValueError, match="query_frames"):
            Layout(calib=False, query_context=1, query_frames=bad)
    with pytest.raises(ValueError, match="query_context"):
        Layout(calib=False, query_context=2, query_frames=(0, 7))


def test_sequences_take_the_layouts_frames(split):
    layout = Layout(calib=True, calib_frames=(0, 7), query_context=1, query_frames=(0, 3, 7))
    seqs = training_sequences(split, layout)
    assert seqs.n_steps == 4 + 3 and seqs.n_context == 5
    assert np.array_equal(seqs.frame[0], [0, 7, 0, 7, 0, 3, 7])
    objects = training_objects(split)
    assert np.array_equal(seqs.clip[:, -1], objects.query) and np.array_equal(seqs.clip[:, 0], objects.calib[:, 0])


def test_states_are_nominal_frame_times_then_the_layouts_rest_state(split):
    layout = Layout(calib=False, query_context=1, query_frames=(0, 1, 4, 7), rest_state=0.5)
    nominal = split.meta[[f"t{k}" for k in range(7)]].median(axis=0).to_numpy()
    assert np.array_equal(layout.frame_states(split.meta), [*nominal, 0.5])
    assert layout.without_calibration().rest_state == 0.5
    seqs = training_sequences(split, layout)
    # a step's state is its frame's, relative to the rest frame's
    assert np.allclose(seqs.state[0], [nominal[0] / 0.5, nominal[1] / 0.5, nominal[4] / 0.5, 1.0])


def test_pooling_averages_blocks_of_patches(split):
    pooled = split.pooled((1, 2))
    assert pooled.grid == (1, 2) and pooled.tokens.shape == (*split.tokens.shape[:2], 2, split.tokens.shape[3])
    grid = split.tokens.astype(np.float32).reshape(*split.tokens.shape[:2], 2, 4, -1)
    expect = grid[:, :, :, 2:].mean(axis=(2, 3))  # the right half of the image
    assert np.allclose(pooled.tokens[:, :, 1].astype(np.float32), expect, atol=2e-3)
    assert np.array_equal(pooled.tokens, pool_tokens(split.tokens, (2, 4), (1, 2)))
    assert split.pooled(None) is split and split.pooled((2, 4)) is split
    with pytest.raises(ValueError, match="does not divide"):
        split.pooled((1, 3))


def test_every_push_is_a_query_once_with_the_other_two_in_speed_order(split):
    objects = training_objects(split)
    speed = split.meta["speed"].to_numpy()
    every = objects.every_push_as_query(speed)
    n = len(objects.object_ids)
    assert len(every.object_ids) == 3 * n
    for i in range(n):
        own = {int(objects.query[i]), *map(int, objects.calib[i])}
        rows = np.flatnonzero(every.object_ids == objects.object_ids[i])
        assert {int(every.query[r]) for r in rows} == own
        for r in rows:
            ctx = every.calib[r]
            assert set(map(int, ctx)) == own - {int(every.query[r])}
            assert speed[ctx[0]] <= speed[ctx[1]]


def test_residual_predictor_predicts_a_change_of_its_input():
    cfg = PredictorConfig(embed_dim=6, grid=(1, 2), max_steps=4, width=16, depth=1, heads=2, residual=True)
    torch.manual_seed(0)
    model = ACPredictor(cfg).eval()
    with torch.no_grad():
        model.out.weight.zero_()
        model.out.bias.zero_()
    x, a, s = torch.randn(2, 4, 2, 6), torch.randn(2, 4, 1), torch.randn(2, 4, 1)
    assert torch.equal(model(x, a, s), x)
