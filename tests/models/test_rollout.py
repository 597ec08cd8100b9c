"""The one rollout loop: what re-running the model on each prefix gives, and the same tokens in training and evaluation."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from test_ac_predictor import tiny_model

from imply.models.config import Layout, TrainConfig
from imply.models.examples import training_sequences
from imply.models.features import load_feature_split
from imply.models.rollout import final_tokens, rollout
from imply.models.train import losses
from synthetic_features import synth_split

# tiny tensors: extra torch threads only contend with the rest of the suite
pytestmark = pytest.mark.usefixtures("one_torch_thread")


def prefix_rollout(model, frames, actions, states, n_context):
    """Reference without a cache: each step predicted by running the model on the whole prefix before it."""
    seq = [frames[:, s] for s in range(n_context)]
    for s in range(n_context, frames.shape[1]):
        seq.append(model(torch.stack(seq, dim=1), actions[:, :s], states[:, :s])[:, -1])
    return torch.stack(seq[n_context:], dim=1)


def test_rollout_is_the_model_rerun_on_each_prefix():
    model = tiny_model().eval()
    x, a, s = torch.randn(2, 6, 4, 8), torch.randn(2, 6, 1), torch.randn(2, 6, 1)
    with torch.no_grad():
        for n_context in (1, 3, 5):
            r = rollout(model, x, a, s, n_context=n_context)
            assert r.shape == (2, 6 - n_context, 4, 8)
            assert torch.allclose(r, prefix_rollout(model, x, a, s, n_context), atol=1e-5)
        # the first rolled-out frame is the teacher-forcing prediction from the context
        assert torch.allclose(rollout(model, x, a, s, n_context=3)[:, 0], model(x, a, s)[:, 2], atol=1e-5)
        assert torch.equal(rollout(model, x, a, s, n_context=3, steps=2), rollout(model, x, a, s, n_context=3)[:, :2])
    with pytest.raises(ValueError, match="do not fit"):
        rollout(model, x, a, s, n_context=6)


def test_training_rollout_term_runs_the_rollout_loop():
    """The loss's rollout continues from the teacher-forcing pass; the same loop from the context alone agrees."""
    model = tiny_model()
    x, a, s = torch.randn(2, 14, 4, 8), torch.randn(2, 14, 1), torch.randn(2, 14, 1)
    cfg = TrainConfig(rollout_steps=4, final_weight=1.0)
    tf, ar = losses(model, x, a, s, n_context=8, tf_weights=torch.tensor([0.0] * 6 + [1.0] * 7), cfg=cfg)
    rolled = rollout(model, x, a, s, n_context=8, steps=4, context_pass=model.run(x, a, s))
    assert torch.equal(ar, (rolled - x[:, 8:12]).abs().mean(dim=(0, 2, 3)).sum() / 4)
    assert torch.allclose(rolled, rollout(model, x, a, s, n_context=8, steps=4), atol=1e-5)
    assert torch.allclose(rolled, prefix_rollout(model, x, a, s, 8)[:, :4], atol=1e-5)
    assert torch.allclose(tf, (model(x, a, s)[:, 6:-1] - x[:, 7:]).abs().mean(), atol=1e-6)
    ar.backward()  # the gradient flows through the fed-back predictions
    assert model.frame_embed.weight.grad is not None and model.frame_embed.weight.grad.abs().sum() > 0


def test_evaluation_reads_the_last_frame_the_training_rollout_predicts(tmp_path):
    split = load_feature_split(*synth_split(tmp_path, "train", 10, False, 1))
    layout = Layout(calib=True, query_context=1, query_frames=(0, 1, 4, 7))
    seqs = training_sequences(split, layout)
    model = tiny_model().eval()
    frames, actions, states = seqs.batch(np.arange(len(seqs)))
    with torch.no_grad():
        trained = rollout(
            model, frames, actions, states, n_context=seqs.n_context, context_pass=model.run(frames, actions, states)
        )
    evaluated = final_tokens(model, seqs, batch_size=4)  # in batches of 4
    assert evaluated.shape == (10, 4, 8)
    assert np.allclose(evaluated, trained[:, -1].numpy(), atol=1e-5)
    assert np.array_equal(evaluated, final_tokens(model, seqs, batch_size=10))
