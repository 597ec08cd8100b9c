"""The masked-latent predictor used only to pretrain the CPU encoder (JEPA objective).

Given the context encoder's tokens of the visible patches and the positions of the
hidden ones, it predicts the target encoder's tokens at the hidden positions: context
tokens are projected to the predictor width, a learned mask token (one per hidden
position) joins them, pre-norm RoPE blocks (:mod:`imply.models.modules`, as the encoder's) mix them with
their 3D positions, and the outputs at the hidden positions are projected back to the
encoder width. Configuration in, tensors out; training lives in :mod:`imply.models.pretrain`.
"""

from __future__ import annotations

import torch
from torch import nn

from imply.models.modules import Block, init_weights, rope_tables, shrink_residual_branches


class MaskedPredictor(nn.Module):
    def __init__(
        self, embed_dim: int, pred_dim: int = 48, depth: int = 2, num_heads: int = 4, mlp_ratio: float = 4.0
    ) -> None:
        super().__init__()
        self.embed = nn.Linear(embed_dim, pred_dim)
        self.mask_token = nn.Parameter(torch.zeros(1, 1, pred_dim))
        self.head_dim = pred_dim // num_heads
        self.blocks = nn.ModuleList([Block(pred_dim, num_heads, mlp_ratio) for _ in range(depth)])
        self.norm = nn.LayerNorm(pred_dim, eps=1e-6)
        self.proj = nn.Linear(pred_dim, embed_dim)
        self.apply(init_weights)
        nn.init.trunc_normal_(self.mask_token, std=0.02)
        shrink_residual_branches(self.blocks)

    def forward(self, ctx: torch.Tensor, ctx_pos: torch.Tensor, tgt_pos: torch.Tensor) -> torch.Tensor:
        """ctx (B, Nc, D) context tokens at positions ctx_pos (B, 3, Nc); predictions (B, Nt, D) at tgt_pos (B, 3, Nt)."""
        b, n_tgt = ctx.shape[0], tgt_pos.shape[-1]
        x = torch.cat([self.embed(ctx), self.mask_token.expand(b, n_tgt, -1)], dim=1)
        rope = rope_tables(torch.cat([ctx_pos, tgt_pos], dim=-1), self.head_dim)
        for blk in self.blocks:
            x, _ = blk(x, rope)
        return self.proj(self.norm(x[:, -n_tgt:]))
