"""A video Vision Transformer of the V-JEPA 2 family (configuration in, tokens out).

The architecture follows V-JEPA 2's encoder so that its released ``.pt`` checkpoints
load into it unchanged (strict key match after prefix stripping, see
:mod:`imply.models.encoder`):

* ``patch_embed.proj``: a Conv3d over tubelets of ``tubelet_size`` frames x
  ``patch_size`` x ``patch_size`` pixels;
* ``blocks.{i}``: pre-norm transformer blocks (``norm1``, ``attn.qkv`` fused, ``attn.proj``,
  ``norm2``, ``mlp.fc1``, ``mlp.fc2``; GELU), LayerNorm eps 1e-6;
* 3D rotary position embeddings inside attention: each head's first 2*floor(d/6) channel
  pairs rotate with time, the next with height, the next with width (the rest are not
  rotated), with V-JEPA 2's frequency layout (kept, including its duplicated-frequency
  quirk, because the released weights were trained with it); no learned positions;
* ``norm``: a final LayerNorm.

Input (B, 3, T, H, W) float, output (B, T/tubelet * H/patch * W/patch, embed_dim),
tokens in (time, row, column) order. ``forward(x, keep=idx)`` runs only the tokens at
``idx`` (B, n_keep) with their own positions, as the JEPA context encoder needs.

Presets: ``tiny`` (the CPU default), and V-JEPA 2's ``vit_large``, ``vit_huge``,
``vit_giant_xformers`` (ViT-g, the V-JEPA 2-AC encoder).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import torch
import torch.nn.functional as F
from torch import nn

from imply.options import known_options


@dataclass(frozen=True)
class ViTConfig:
    """Architecture of :class:`VisionTransformer`."""

    patch_size: int = 16
    tubelet_size: int = 2
    in_chans: int = 3
    embed_dim: int = 64
    depth: int = 4
    num_heads: int = 4
    mlp_ratio: float = 4.0
    qkv_bias: bool = True

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> ViTConfig:
        return cls(**known_options(cls, d, "encoder architecture"))

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


PRESETS: dict[str, ViTConfig] = {
    "tiny": ViTConfig(embed_dim=64, depth=4, num_heads=4),
    "vit_large": ViTConfig(embed_dim=1024, depth=24, num_heads=16),
    "vit_huge": ViTConfig(embed_dim=1280, depth=32, num_heads=16),
    "vit_giant_xformers": ViTConfig(embed_dim=1408, depth=40, num_heads=22, mlp_ratio=48 / 11),
}


def rope_tables(pos: torch.Tensor, head_dim: int) -> tuple[torch.Tensor, torch.Tensor]:
    """cos and sin tables (B, 1, N, 3a) of 3D RoPE for positions ``pos`` (B, 3, N).

    Each head's first 3a channels (a = 2 * floor(head_dim / 6)) rotate in adjacent
    pairs: a channels by time, a by row, a by column. Within an axis the sin/cos
    tables are tiled ([f_0..f_{a/2-1}, f_0..f_{a/2-1}]) while the rotated pairs are
    adjacent channels; V-JEPA 2 ships weights trained this way, so we keep it. Tables
    are computed once per forward pass and shared by every block.
    """
    a = 2 * ((head_dim // 3) // 2)
    omega = 1.0 / 10000 ** (torch.arange(a // 2, dtype=torch.float32, device=pos.device) / (a / 2.0))
    freq = pos.float().unsqueeze(-1) * omega  # (B, 3, N, a/2)
    freq = torch.cat([freq, freq], dim=-1)  # (B, 3, N, a)
    freq = freq.permute(0, 2, 1, 3).flatten(2).unsqueeze(1)  # (B, 1, N, 3a)
    return freq.cos(), freq.sin()


def rope_apply(x: torch.Tensor, rope: tuple[torch.Tensor, torch.Tensor]) -> torch.Tensor:
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
    def __init__(self, dim: int, num_heads: int, qkv_bias: bool = True) -> None:
        super().__init__()
        self.num_heads = num_heads
        self.head_dim = dim // num_heads
        self.qkv = nn.Linear(dim, dim * 3, bias=qkv_bias)
        self.proj = nn.Linear(dim, dim)

    def forward(
        self, x: torch.Tensor, rope: tuple[torch.Tensor, torch.Tensor], attn_mask: torch.Tensor | None = None
    ) -> torch.Tensor:
        """x (B, N, C); rope tables from :func:`rope_tables`; attn_mask boolean (N, N) or None."""
        b, n, c = x.shape
        q, k, v = self.qkv(x).unflatten(-1, (3, self.num_heads, -1)).permute(2, 0, 3, 1, 4)
        out = F.scaled_dot_product_attention(rope_apply(q, rope), rope_apply(k, rope), v, attn_mask=attn_mask)
        return self.proj(out.transpose(1, 2).reshape(b, n, c))


class MLP(nn.Module):
    def __init__(self, dim: int, hidden: int) -> None:
        super().__init__()
        self.fc1 = nn.Linear(dim, hidden)
        self.act = nn.GELU()
        self.fc2 = nn.Linear(hidden, dim)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.fc2(self.act(self.fc1(x)))


class Block(nn.Module):
    def __init__(self, dim: int, num_heads: int, mlp_ratio: float, qkv_bias: bool = True) -> None:
        super().__init__()
        self.norm1 = nn.LayerNorm(dim, eps=1e-6)
        self.attn = RoPEAttention(dim, num_heads, qkv_bias)
        self.norm2 = nn.LayerNorm(dim, eps=1e-6)
        self.mlp = MLP(dim, int(dim * mlp_ratio))

    def forward(
        self, x: torch.Tensor, rope: tuple[torch.Tensor, torch.Tensor], attn_mask: torch.Tensor | None = None
    ) -> torch.Tensor:
        x = x + self.attn(self.norm1(x), rope, attn_mask)
        return x + self.mlp(self.norm2(x))


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
        if cfg.embed_dim % cfg.num_heads:
            raise ValueError("embed_dim must be a multiple of num_heads")
        self.cfg = cfg
        self.patch_embed = PatchEmbed3D(cfg)
        self.blocks = nn.ModuleList(
            [Block(cfg.embed_dim, cfg.num_heads, cfg.mlp_ratio, cfg.qkv_bias) for _ in range(cfg.depth)]
        )
        self.norm = nn.LayerNorm(cfg.embed_dim, eps=1e-6)
        self.apply(init_weights)
        for i, blk in enumerate(self.blocks):
            # deeper residual branches start smaller, as in V-JEPA 2
            blk.attn.proj.weight.data.div_(math.sqrt(2.0 * (i + 1)))
            blk.mlp.fc2.weight.data.div_(math.sqrt(2.0 * (i + 1)))

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
            tokens = blk(tokens, rope)
        return self.norm(tokens)


def init_weights(m: nn.Module) -> None:
    """Truncated-normal linear and convolution weights, zero biases, unit layer norms."""
    if isinstance(m, (nn.Linear, nn.Conv3d)):
        nn.init.trunc_normal_(m.weight, std=0.02)
        if m.bias is not None:
            nn.init.zeros_(m.bias)
    elif isinstance(m, nn.LayerNorm):
        nn.init.ones_(m.weight)
        nn.init.zeros_(m.bias)
