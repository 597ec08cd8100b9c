"""A video Vision Transformer of the V-JEPA 2 family (configuration in, tokens out).

The architecture follows V-JEPA 2's encoder so that its released ``.pt`` checkpoints
load into it unchanged (strict key match after prefix stripping, see
:mod:`imply.models.encoder`):

* ``patch_embed.proj``: a Conv3d over tubelets of ``tubelet_size`` frames x
  ``patch_size`` x ``patch_size`` pixels;
* ``blocks.{i}``: pre-norm transformer blocks of :mod:`imply.models.modules` (``norm1``,
  ``attn.qkv`` fused, ``attn.proj``, ``norm2``, ``mlp.fc1``, ``mlp.fc2``; GELU), LayerNorm eps 1e-6;
* 3D rotary position embeddings inside attention, with V-JEPA 2's frequency layout
  (:func:`imply.models.modules.rope_tables`); no learned positions;
* ``norm``: a final LayerNorm.

Input (B, 3, T, H, W) float, output (B, T/tubelet * H/patch * W/patch, embed_dim),
tokens in (time, row, column) order. ``forward(x, keep=idx)`` runs only the tokens at
``idx`` (B, n_keep) with their own positions, as the JEPA context encoder needs.

Presets: ``tiny`` (the CPU default), and V-JEPA 2's ``vit_large``, ``vit_huge``,
``vit_giant_xformers`` (ViT-g, the V-JEPA 2-AC encoder).
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from torch import nn

from imply.models.config import ViTConfig
from imply.models.modules import Block, grid_positions, init_weights, rope_tables, shrink_residual_branches

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


class PatchEmbed3D(nn.Module):
    def __init__(self, cfg: ViTConfig) -> None:
        super().__init__()
        k = (cfg.tubelet_size, cfg.patch_size, cfg.patch_size)
        self.proj = nn.Conv3d(cfg.in_chans, cfg.embed_dim, kernel_size=k, stride=k)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.proj(x).flatten(2).transpose(1, 2)


class VisionTransformer(nn.Module):
    """V-JEPA 2-style video ViT; see the module docstring for layout and key names."""

    def __init__(self, cfg: ViTConfig) -> None:
        super().__init__()
        self.cfg = cfg
        self.patch_embed = PatchEmbed3D(cfg)
        self.blocks = nn.ModuleList(
            [Block(cfg.embed_dim, cfg.num_heads, cfg.mlp_ratio, cfg.qkv_bias) for _ in range(cfg.depth)]
        )
        self.norm = nn.LayerNorm(cfg.embed_dim, eps=1e-6)
        self.apply(init_weights)
        shrink_residual_branches(self.blocks)

    def grid(self, t: int, h: int, w: int) -> tuple[int, int, int]:
        c = self.cfg
        return t // c.tubelet_size, h // c.patch_size, w // c.patch_size

    def forward(self, x: torch.Tensor, keep: torch.Tensor | None = None) -> torch.Tensor:
        """Tokens of video ``x`` (B, C, T, H, W); with ``keep`` (B, n) only those tokens."""
        b, _, t, h, w = x.shape
        pos = grid_positions(*self.grid(t, h, w), device=x.device).unsqueeze(0)
        tokens = self.patch_embed(x)
        if keep is not None:
            tokens = torch.gather(tokens, 1, keep.unsqueeze(-1).expand(-1, -1, tokens.shape[-1]))
            pos = torch.gather(pos.expand(b, -1, -1), 2, keep.unsqueeze(1).expand(-1, 3, -1))
        rope = rope_tables(pos, self.cfg.embed_dim // self.cfg.num_heads)
        for blk in self.blocks:
            tokens, _ = blk(tokens, rope)
        return self.norm(tokens)


def preprocess(frames: np.ndarray | torch.Tensor, input_size: tuple[int, int], tubelet: int = 2) -> torch.Tensor:
    """uint8 (N, H, W, 3) -> float (N, 3, tubelet, h, w): resized, ImageNet-normalised, duplicated in time."""
    x = torch.as_tensor(np.asarray(frames)).permute(0, 3, 1, 2).float() / 255.0
    if tuple(x.shape[-2:]) != tuple(input_size):
        x = F.interpolate(x, size=tuple(input_size), mode="bilinear", align_corners=False, antialias=True)
    mean = torch.tensor(IMAGENET_MEAN).view(1, 3, 1, 1)
    std = torch.tensor(IMAGENET_STD).view(1, 3, 1, 1)
    x = (x - mean) / std
    return x.unsqueeze(2).expand(-1, -1, tubelet, -1, -1).contiguous()
