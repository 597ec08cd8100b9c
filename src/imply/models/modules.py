"""Building blocks shared by every transformer of the package: 3D rotary positions, attention, MLP, block.

The frozen encoder (:mod:`imply.models.vision_transformer`), its pretraining predictor
(:mod:`imply.models.masked_predictor`) and the action-conditioned predictor
(:mod:`imply.models.ac_predictor`) all use these, as V-JEPA 2's models share one modules
file. Key names (``norm1``, ``attn.qkv``, ``attn.proj``, ``norm2``, ``mlp.fc1``,
``mlp.fc2``) are V-JEPA 2's, so its released encoder weights load unchanged.

Rotary positions: each head's first 3a channels (a = 2 * floor(head_dim / 6)) rotate in
adjacent pairs, a channels by time, a by row, a by column; the rest are not rotated.
Within an axis the sin/cos tables are tiled ([f_0..f_{a/2-1}, f_0..f_{a/2-1}]) while
the rotated pairs are adjacent channels: V-JEPA 2 ships weights trained that way, so
it is kept. Tokens without a place on the image (the predictor's action and state
tokens) are rotated in time only: their row and column angles are zero.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

Rope = tuple[torch.Tensor, torch.Tensor]
KeyValue = tuple[torch.Tensor, torch.Tensor]


def rope_tables(
    pos: torch.Tensor, head_dim: int, *, spatial: torch.Tensor | None = None, theta: float = 10000.0
) -> Rope:
    """cos and sin tables (B, 1, N, 3a) of 3D RoPE for positions ``pos`` (B, 3, N) = (time, row, column).

    ``spatial`` (N,) bool, when given, marks the tokens with a place on the image; the
    others get the time rotation only. Tables are computed once per forward pass and
    shared by every block.
    """
    a = 2 * ((head_dim // 3) // 2)  # 0 for heads narrower than 6 channels: nothing rotates
    pos = pos.float()
    if spatial is not None:
        keep = torch.stack([torch.ones_like(spatial, dtype=pos.dtype), spatial.to(pos.dtype), spatial.to(pos.dtype)])
        pos = pos * keep
    omega = 1.0 / theta ** (torch.arange(a // 2, dtype=torch.float32, device=pos.device) / (a / 2.0))
    freq = pos.unsqueeze(-1) * omega  # (B, 3, N, a/2)
    freq = torch.cat([freq, freq], dim=-1)  # (B, 3, N, a)
    freq = freq.permute(0, 2, 1, 3).flatten(2).unsqueeze(1)  # (B, 1, N, 3a)
    return freq.cos(), freq.sin()


def rope_apply(x: torch.Tensor, rope: Rope) -> torch.Tensor:
    """Rotate the first 3a channels of ``x`` (B, heads, N, head_dim) with tables from :func:`rope_tables`."""
    cos, sin = rope
    r = cos.shape[-1]
    head, rest = x[..., :r], x[..., r:]
    pairs = head.unflatten(-1, (-1, 2))
    turned = torch.stack((-pairs[..., 1], pairs[..., 0]), dim=-1).flatten(-2)
    return torch.cat([head * cos + turned * sin, rest], dim=-1)


def grid_positions(n_t: int, n_h: int, n_w: int, device=None) -> torch.Tensor:
    """(3, n_t*n_h*n_w) time, row and column index of each token in (t, h, w) order."""
    t, h, w = torch.meshgrid(
        torch.arange(n_t, device=device),
        torch.arange(n_h, device=device),
        torch.arange(n_w, device=device),
        indexing="ij",
    )
    return torch.stack([t.reshape(-1), h.reshape(-1), w.reshape(-1)]).float()


class RoPEAttention(nn.Module):
    """Multi-head self-attention with 3D rotary positions, an optional mask and a key/value cache."""

    def __init__(self, dim: int, num_heads: int, qkv_bias: bool = True) -> None:
        super().__init__()
        if dim % num_heads:
            raise ValueError(f"width {dim} is not divisible by {num_heads} heads")
        self.num_heads = num_heads
        self.head_dim = dim // num_heads
        self.qkv = nn.Linear(dim, dim * 3, bias=qkv_bias)
        self.proj = nn.Linear(dim, dim)

    def forward(
        self, x: torch.Tensor, rope: Rope, attn_mask: torch.Tensor | None = None, past: KeyValue | None = None
    ) -> tuple[torch.Tensor, KeyValue]:
        """x (B, N, C); rope tables of x's tokens; attn_mask boolean (N, N_past + N) or None.

        ``past``: rotated keys and values of earlier tokens (B, heads, N_past, head_dim),
        which x's tokens attend to as well. Returns the output and the keys and values of
        past and present tokens.
        """
        b, n, c = x.shape
        q, k, v = self.qkv(x).unflatten(-1, (3, self.num_heads, -1)).permute(2, 0, 3, 1, 4)
        q, k = rope_apply(q, rope), rope_apply(k, rope)
        if past is not None:
            k = torch.cat([past[0], k], dim=2)
            v = torch.cat([past[1], v], dim=2)
        out = F.scaled_dot_product_attention(q, k, v, attn_mask=attn_mask)
        return self.proj(out.transpose(1, 2).reshape(b, n, c)), (k, v)


class MLP(nn.Module):
    def __init__(self, dim: int, hidden: int) -> None:
        super().__init__()
        self.fc1 = nn.Linear(dim, hidden)
        self.act = nn.GELU()
        self.fc2 = nn.Linear(hidden, dim)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc2(self.act(self.fc1(x)))


class Block(nn.Module):
    """Pre-norm transformer block: RoPE attention then MLP, each on a residual branch."""

    def __init__(self, dim: int, num_heads: int, mlp_ratio: float, qkv_bias: bool = True) -> None:
        super().__init__()
        self.norm1 = nn.LayerNorm(dim, eps=1e-6)
        self.attn = RoPEAttention(dim, num_heads, qkv_bias)
        self.norm2 = nn.LayerNorm(dim, eps=1e-6)
        self.mlp = MLP(dim, int(dim * mlp_ratio))

    def forward(
        self, x: torch.Tensor, rope: Rope, attn_mask: torch.Tensor | None = None, past: KeyValue | None = None
    ) -> tuple[torch.Tensor, KeyValue]:
        """The block's output and the attention's keys and values (see :meth:`RoPEAttention.forward`)."""
        a, kv = self.attn(self.norm1(x), rope, attn_mask, past)
        x = x + a
        return x + self.mlp(self.norm2(x)), kv


def init_weights(m: nn.Module) -> None:
    """Truncated-normal linear and convolution weights, zero biases, unit layer norms."""
    if isinstance(m, (nn.Linear, nn.Conv3d)):
        nn.init.trunc_normal_(m.weight, std=0.02)
        if m.bias is not None:
            nn.init.zeros_(m.bias)
    elif isinstance(m, nn.LayerNorm):
        nn.init.ones_(m.weight)
        nn.init.zeros_(m.bias)


def shrink_residual_branches(blocks: nn.ModuleList) -> None:
    """Scale each block's output projections by 1/sqrt(2 (i + 1)): deeper residual branches start smaller."""
    for i, blk in enumerate(blocks):
        blk.attn.proj.weight.data.div_(math.sqrt(2.0 * (i + 1)))
        blk.mlp.fc2.weight.data.div_(math.sqrt(2.0 * (i + 1)))
