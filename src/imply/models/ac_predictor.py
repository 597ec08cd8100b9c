"""The V-JEPA 2-AC action-conditioned predictor, re-implemented for the push scene.

What it is: a transformer over a sequence of time steps. Each step contributes, in
this order, one *action* token (the pusher's commanded speed for the push the frame
belongs to), one *state* token (the pusher state at that frame, see below) and the
frame's encoder patch tokens. Encoder tokens (width ``embed_dim``) are projected to
the predictor width; actions and states have their own linear encoders.

* Attention is block-causal: every token of step t attends to all tokens of steps
  <= t and none of later steps (:func:`block_causal_mask`). So the output at the
  patch tokens of step t can only depend on frames, actions and states up to t, and
  it is read as the prediction of the next step's frame tokens.
* Positions are 3D rotary embeddings (:class:`Rope3D`): each head's channels are
  split into a time, a height and a width part, each rotated by its coordinate.
  Action and state tokens sit at their step's time but have no place on the image,
  so they are rotated in time only (their height/width channels pass unrotated).
* Outputs at patch tokens are normalised and projected back to ``embed_dim``; the
  targets are the encoder tokens passed through a parameter-free layer norm
  (:func:`normalise_tokens`), and the inputs are normalised the same way, so a
  rollout can feed its own predictions back in.

The *state* here: V-JEPA 2-AC conditions on the robot's end-effector state. Our
pusher is a velocity-servoed puck whose trajectory within a clip is fixed by its
commanded speed and the time since the push began, and the clip metadata carries the
frame times but no measured pusher pose. So the state token is the frame time,
divided by the clip's last frame time (``state_dim = 1``); with the action token it
pins the pusher's nominal state. Calibration frames carry their own push's speed and
frame time, which is how the model tells which push and which moment a frame shows.

The public facebookresearch/vjepa2 code (src/models/ac_predictor.py) defines the
behaviour this follows; the code here is written from that description. Presets:
``tiny`` (CPU default) and ``vitg-300m`` (depth 24, width 1024, 16 heads: the size
of the paper's predictor) live in config (``model.presets``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import torch
import torch.nn.functional as F
from torch import nn

from imply.models.vision_transformer import init_weights
from imply.options import known_options


@dataclass(frozen=True)
class PredictorConfig:
    """Shape of a predictor. ``embed_dim``/``grid`` come from the encoder features."""

    embed_dim: int
    grid: tuple[int, int]
    width: int = 96
    depth: int = 3
    heads: int = 4
    mlp_ratio: float = 4.0
    action_dim: int = 1
    state_dim: int = 1
    max_steps: int = 32
    rope_theta: float = 10000.0

    @classmethod
    def from_dict(cls, d: dict) -> PredictorConfig:
        kw = known_options(cls, d, "predictor")
        if "grid" in kw:
            kw["grid"] = tuple(int(g) for g in kw["grid"])
        return cls(**kw)

    def to_dict(self) -> dict:
        out = {f.name: getattr(self, f.name) for f in fields(self)}
        out["grid"] = list(self.grid)
        return out

    @property
    def n_patches(self) -> int:
        return self.grid[0] * self.grid[1]

    @property
    def tokens_per_step(self) -> int:
        # one action token, one state token, then the patches
        return 2 + self.n_patches


def normalise_tokens(x: torch.Tensor) -> torch.Tensor:
    """Parameter-free layer norm over the feature axis: the targets (and inputs)."""
    return F.layer_norm(x, (x.shape[-1],))


def block_causal_mask(n_steps: int, tokens_per_step: int, device=None) -> torch.Tensor:
    """(L, L) boolean mask, True where query token i may attend key token j.

    Token i belongs to step i // tokens_per_step; it sees every token of its own and
    earlier steps.
    """
    step = torch.arange(n_steps * tokens_per_step, device=device) // tokens_per_step
    return step[None, :] <= step[:, None]


def token_positions(n_steps: int, grid: tuple[int, int], device=None) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-token (time, height, width) coordinates and a flag for spatial rotation.

    Returns ``pos`` (L, 3) float and ``spatial`` (L,) bool; action and state tokens
    have spatial=False (rotated in time only).
    """
    gh, gw = grid
    hh, ww = torch.meshgrid(torch.arange(gh), torch.arange(gw), indexing="ij")
    patch_hw = torch.stack([hh.reshape(-1), ww.reshape(-1)], dim=1).float()
    per_step = torch.cat([torch.zeros(2, 2), patch_hw], dim=0)  # action, state, patches
    spatial_step = torch.cat([torch.zeros(2, dtype=torch.bool), torch.ones(gh * gw, dtype=torch.bool)])
    t = torch.arange(n_steps).float().repeat_interleave(per_step.shape[0])[:, None]
    pos = torch.cat([t, per_step.repeat(n_steps, 1)], dim=1)
    return pos.to(device), spatial_step.repeat(n_steps).to(device)


class Rope3D(nn.Module):
    """Rotary embedding over (time, height, width) on a head's channels.

    The head dimension is split into three equal even-sized parts (any remainder is
    left unrotated); part a is rotated by coordinate a. Tokens without a place on the
    image (spatial=False) get the time rotation only.
    """

    def __init__(self, head_dim: int, theta: float = 10000.0):
        super().__init__()
        part = 2 * ((head_dim // 3) // 2)
        if part == 0:
            raise ValueError(f"head dimension {head_dim} is too small for 3D rotary embeddings")
        self.part = part
        inv = 1.0 / (theta ** (torch.arange(0, part, 2).float() / part))
        self.register_buffer("inv_freq", inv, persistent=False)

    def angles(self, pos: torch.Tensor, spatial: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """cos, sin of shape (L, 3 * part // 2) for the given token coordinates."""
        ang = pos[:, :, None] * self.inv_freq[None, None, :]  # (L, 3, part/2)
        ang[:, 1:, :] = ang[:, 1:, :] * spatial[:, None, None].to(ang.dtype)
        ang = ang.reshape(pos.shape[0], -1)
        return ang.cos(), ang.sin()

    def rotate(self, x: torch.Tensor, cos: torch.Tensor, sin: torch.Tensor) -> torch.Tensor:
        """Rotate x (B, H, L, head_dim): channel pairs (2i, 2i+1) of the rotated span."""
        n = 3 * self.part
        xr, rest = x[..., :n], x[..., n:]
        x1, x2 = xr[..., 0::2], xr[..., 1::2]
        r1 = x1 * cos - x2 * sin
        r2 = x1 * sin + x2 * cos
        out = torch.stack([r1, r2], dim=-1).flatten(-2)
        return torch.cat([out, rest], dim=-1)


class Attention(nn.Module):
    def __init__(self, width: int, heads: int, rope: Rope3D):
        super().__init__()
        if width % heads:
            raise ValueError(f"width {width} is not divisible by {heads} heads")
        self.heads = heads
        self.qkv = nn.Linear(width, 3 * width)
        self.proj = nn.Linear(width, width)
        self.rope = rope

    def forward(self, x, mask, cos, sin, past=None):
        """Attention of x's tokens to ``past`` keys/values (rotated, cached) and their own.

        Returns (output, (k, v)) with k, v covering past and present tokens.
        """
        b, n, w = x.shape
        qkv = self.qkv(x).reshape(b, n, 3, self.heads, w // self.heads).permute(2, 0, 3, 1, 4)
        q, k, v = qkv[0], qkv[1], qkv[2]
        q = self.rope.rotate(q, cos, sin)
        k = self.rope.rotate(k, cos, sin)
        if past is not None:
            k = torch.cat([past[0], k], dim=2)
            v = torch.cat([past[1], v], dim=2)
        out = F.scaled_dot_product_attention(q, k, v, attn_mask=mask)
        return self.proj(out.transpose(1, 2).reshape(b, n, w)), (k, v)


class Block(nn.Module):
    def __init__(self, width: int, heads: int, mlp_ratio: float, rope: Rope3D):
        super().__init__()
        self.norm1 = nn.LayerNorm(width)
        self.attn = Attention(width, heads, rope)
        self.norm2 = nn.LayerNorm(width)
        hidden = int(width * mlp_ratio)
        self.mlp = nn.Sequential(nn.Linear(width, hidden), nn.GELU(), nn.Linear(hidden, width))

    def forward(self, x, mask, cos, sin, past=None):
        a, kv = self.attn(self.norm1(x), mask, cos, sin, past)
        x = x + a
        return x + self.mlp(self.norm2(x)), kv


class ACPredictor(nn.Module):
    """Action-conditioned latent predictor (see the module docstring)."""

    def __init__(self, cfg: PredictorConfig):
        super().__init__()
        self.cfg = cfg
        w = cfg.width
        self.frame_embed = nn.Linear(cfg.embed_dim, w)
        self.action_embed = nn.Linear(cfg.action_dim, w)
        self.state_embed = nn.Linear(cfg.state_dim, w)
        rope = Rope3D(w // cfg.heads, cfg.rope_theta)
        self.blocks = nn.ModuleList([Block(w, cfg.heads, cfg.mlp_ratio, rope) for _ in range(cfg.depth)])
        self.norm = nn.LayerNorm(w)
        self.out = nn.Linear(w, cfg.embed_dim)
        self.apply(init_weights)
        # residual branches start small in deep stacks, as in ViT-style predictors
        for i, blk in enumerate(self.blocks):
            blk.attn.proj.weight.data.div_(math.sqrt(2.0 * (i + 1)))
            blk.mlp[2].weight.data.div_(math.sqrt(2.0 * (i + 1)))

    def forward(self, frames: torch.Tensor, actions: torch.Tensor, states: torch.Tensor) -> torch.Tensor:
        """Predict the next step's frame tokens at every step.

        frames: (B, T, P, embed_dim) normalised encoder tokens; actions: (B, T,
        action_dim); states: (B, T, state_dim). Returns (B, T, P, embed_dim): entry t
        is the prediction of frame t + 1 from steps <= t.
        """
        return self._run(frames, actions, states, 0, None)[0]

    def _run(self, frames, actions, states, t0: int, cache):
        """Steps t0 .. t0+T-1 given cached keys/values of steps < t0 (None when t0 = 0).

        Returns (predictions (B, T, P, D), new cache covering steps < t0 + T).
        """
        b, t, p, _ = frames.shape
        cfg = self.cfg
        if p != cfg.n_patches:
            raise ValueError(f"expected {cfg.n_patches} patch tokens per frame, got {p}")
        if t0 + t > cfg.max_steps:
            raise ValueError(f"sequence of {t0 + t} steps exceeds max_steps={cfg.max_steps}")
        tps = cfg.tokens_per_step
        tok = torch.cat(
            [self.action_embed(actions)[:, :, None], self.state_embed(states)[:, :, None], self.frame_embed(frames)],
            dim=2,
        ).reshape(b, t * tps, cfg.width)
        # new tokens see every cached (earlier) token and, block-causally, each other
        mask = block_causal_mask(t, tps, device=frames.device)
        if t0:
            mask = torch.cat([torch.ones(t * tps, t0 * tps, dtype=torch.bool, device=frames.device), mask], dim=1)
        if t == 1:
            mask = None  # one step attends to everything before and within it
        pos, spatial = token_positions(t0 + t, cfg.grid, device=frames.device)
        pos, spatial = pos[t0 * tps :], spatial[t0 * tps :]
        cos, sin = self.blocks[0].attn.rope.angles(pos, spatial) if cfg.depth else (None, None)
        new_cache = []
        for i, blk in enumerate(self.blocks):
            tok, kv = blk(tok, mask, cos, sin, None if cache is None else cache[i])
            new_cache.append(kv)
        tok = self.norm(tok).reshape(b, t, tps, cfg.width)[:, :, 2:]
        return self.out(tok), new_cache

    def n_parameters(self) -> int:
        return sum(p.numel() for p in self.parameters())


def rollout(
    model: ACPredictor,
    frames: torch.Tensor,
    actions: torch.Tensor,
    states: torch.Tensor,
    n_context: int,
    first: torch.Tensor | None = None,
) -> torch.Tensor:
    """Auto-regressive latent rollout: keep the first ``n_context`` steps of ``frames``
    and replace every later frame by the model's prediction from the steps before it.

    Returns (B, T, P, D): the context frames followed by predicted frames. Because
    attention is block-causal, running the model on the first s steps gives exactly
    the outputs it would give on a longer sequence, so each step runs on a prefix.
    ``first``, when given, is the already computed prediction of step ``n_context``
    from the true context (a teacher-forcing pass gives it for free). Differentiable
    (used for the training rollout loss) and deterministic.
    """
    t = frames.shape[1]
    if not 1 <= n_context <= t:
        raise ValueError(f"n_context must be in 1..{t}, got {n_context}")
    seq = [frames[:, s] for s in range(n_context)]
    if first is not None and n_context < t:
        seq.append(first)
    for s in range(len(seq), t):
        cur = torch.stack(seq, dim=1)
        pred = model(cur, actions[:, :s], states[:, :s])[:, -1]
        seq.append(pred)
    return torch.stack(seq, dim=1)


@torch.no_grad()
def rollout_cached(
    model: ACPredictor, frames: torch.Tensor, actions: torch.Tensor, states: torch.Tensor, n_context: int
) -> torch.Tensor:
    """:func:`rollout` for inference, with cached keys and values: the context runs once,
    then each new step runs only its own tokens against the cache (same result, up to
    floating-point summation order)."""
    t = frames.shape[1]
    if not 1 <= n_context <= t:
        raise ValueError(f"n_context must be in 1..{t}, got {n_context}")
    pred, cache = model._run(frames[:, :n_context], actions[:, :n_context], states[:, :n_context], 0, None)
    seq = [frames[:, s] for s in range(n_context)]
    nxt = pred[:, -1]
    for s in range(n_context, t):
        seq.append(nxt)
        if s + 1 < t:
            pred, cache = model._run(nxt[:, None], actions[:, s : s + 1], states[:, s : s + 1], s, cache)
            nxt = pred[:, -1]
    return torch.stack(seq, dim=1)
