"""The action-conditioned predictor: block-causal mask, rotary positions of action and state tokens."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from imply.models.ac_predictor import ACPredictor, block_causal_mask, token_positions
from imply.models.config import PredictorConfig
from imply.models.modules import rope_apply, rope_tables

# tiny tensors: extra torch threads only contend with the rest of the suite
pytestmark = pytest.mark.usefixtures("one_torch_thread")

TINY = {"width": 32, "depth": 2, "heads": 2}


def tiny_model(grid=(2, 2), dim=8, steps=14) -> ACPredictor:
    torch.manual_seed(0)
    return ACPredictor(PredictorConfig(embed_dim=dim, grid=grid, max_steps=steps, **TINY))


def test_mask_is_block_causal():
    m = block_causal_mask(3, 4)
    step = np.arange(12) // 4
    assert np.array_equal(m.numpy(), step[None, :] <= step[:, None])
    # functional: a change at step 2 leaves outputs at steps 0-1 unchanged; a change at step 0 reaches step 2
    model = tiny_model().eval()
    x, a, s = torch.randn(1, 4, 4, 8), torch.randn(1, 4, 1), torch.randn(1, 4, 1)
    y = model(x, a, s)
    x2 = x.clone()
    x2[:, 2] += 1.0
    a2 = a.clone()
    a2[:, 3] += 1.0
    y2 = model(x2, a2, s)
    assert torch.allclose(y[:, :2], y2[:, :2], atol=1e-6)
    assert not torch.allclose(y[:, 2:], y2[:, 2:], atol=1e-4)
    x3 = x.clone()
    x3[:, 0] += 1.0
    assert not torch.allclose(model(x3, a, s)[:, 2], y[:, 2], atol=1e-4)


def test_rope_rotates_action_and_state_in_time_only():
    head_dim = 12
    part = 2 * ((head_dim // 3) // 2)  # channels per axis
    pos, spatial = token_positions(2, (2, 3))
    tps = 2 + 6
    assert not spatial[0] and not spatial[1] and spatial[2:tps].all()
    rope = rope_tables(pos, head_dim, spatial=spatial)
    x = torch.randn(1, 1, pos.shape[-1], head_dim)
    y = rope_apply(x, rope)
    # action/state tokens: height and width channels untouched, time channels rotated at step 1
    for i in (tps, tps + 1):
        assert torch.allclose(y[0, 0, i, part:], x[0, 0, i, part:])
        assert not torch.allclose(y[0, 0, i, :part], x[0, 0, i, :part])
    # a patch token off the origin has its spatial channels rotated
    last = 2 * tps - 1
    assert not torch.allclose(y[0, 0, last, part : 3 * part], x[0, 0, last, part : 3 * part])
    # step 0's action token sits at the origin: nothing turns
    assert torch.equal(y[0, 0, 0], x[0, 0, 0])


def test_predictor_and_encoder_share_one_rotary_implementation():
    """Without spatial flags the predictor's tables are the encoder's (V-JEPA 2's layout)."""
    pos = torch.randn(1, 3, 7)
    cos_a, sin_a = rope_tables(pos, 12)
    cos_b, sin_b = rope_tables(pos, 12, spatial=torch.ones(7, dtype=torch.bool))
    assert torch.equal(cos_a, cos_b) and torch.equal(sin_a, sin_b)
