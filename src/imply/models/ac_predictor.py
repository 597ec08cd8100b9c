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
* Positions are 3D rotary embeddings, the encoder's own (:func:`imply.models.modules.rope_tables`):
  each head's channels have a time, a height and a width part, each rotated by its
  coordinate. Action and state tokens sit at their step's time but have no place on the
  image, so they are rotated in time only.
* Outputs at patch tokens are normalised and projected back to ``embed_dim``. With
  ``residual`` the projection is added to the step's own input tokens, so the model
  predicts how the frame changes rather than the whole frame: most of a frame (table,
  background) does not change, and a plain output must relearn it at every step. The
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

import torch
import torch.nn.functional as F
from torch import nn

from imply.models.config import PredictorConfig
from imply.models.modules import Block, KeyValue, Rope, init_weights, rope_tables, shrink_residual_branches


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
    """Per-token (time, row, column) coordinates and a flag for spatial rotation.

    Returns ``pos`` (1, 3, L) float, as :func:`imply.models.modules.rope_tables` takes
    it, and ``spatial`` (L,) bool: False for action and state tokens (rotated in time only).
    """
    gh, gw = grid
    hh, ww = torch.meshgrid(torch.arange(gh), torch.arange(gw), indexing="ij")
    patch_hw = torch.stack([hh.reshape(-1), ww.reshape(-1)], dim=1).float()
    per_step = torch.cat([torch.zeros(2, 2), patch_hw], dim=0)  # action, state, patches
    spatial_step = torch.cat([torch.zeros(2, dtype=torch.bool), torch.ones(gh * gw, dtype=torch.bool)])
    t = torch.arange(n_steps).float().repeat_interleave(per_step.shape[0])[:, None]
    pos = torch.cat([t, per_step.repeat(n_steps, 1)], dim=1)
    return pos.T[None].to(device), spatial_step.repeat(n_steps).to(device)


class ACPredictor(nn.Module):
    """Action-conditioned latent predictor (see the module docstring)."""

    def __init__(self, cfg: PredictorConfig):
        super().__init__()
        self.cfg = cfg
        w = cfg.width
        self.frame_embed = nn.Linear(cfg.embed_dim, w)
        self.action_embed = nn.Linear(cfg.action_dim, w)
        self.state_embed = nn.Linear(cfg.state_dim, w)
        self.blocks = nn.ModuleList([Block(w, cfg.heads, cfg.mlp_ratio) for _ in range(cfg.depth)])
        self.norm = nn.LayerNorm(w, eps=1e-6)
        self.out = nn.Linear(w, cfg.embed_dim)
        self.apply(init_weights)
        shrink_residual_branches(self.blocks)
        self._position_cache: dict[tuple[int, int, str], tuple[torch.Tensor | None, Rope]] = {}

    def forward(self, frames: torch.Tensor, actions: torch.Tensor, states: torch.Tensor) -> torch.Tensor:
        """Predict the next step's frame tokens at every step.

        frames: (B, T, P, embed_dim) normalised encoder tokens; actions: (B, T,
        action_dim); states: (B, T, state_dim). Returns (B, T, P, embed_dim): entry t
        is the prediction of frame t + 1 from steps <= t.
        """
        return self.run(frames, actions, states)[0]

    def run(
        self,
        frames: torch.Tensor,
        actions: torch.Tensor,
        states: torch.Tensor,
        *,
        t0: int = 0,
        cache: list[KeyValue] | None = None,
    ) -> tuple[torch.Tensor, list[KeyValue]]:
        """Steps t0 .. t0+T-1 given cached keys/values of steps < t0 (None when t0 = 0).

        Returns (predictions (B, T, P, D), new cache covering steps < t0 + T): what a
        rollout (:func:`imply.models.rollout.rollout`) continues from.
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
        mask, rope = self._positions(t0, t, frames.device)
        new_cache = []
        for i, blk in enumerate(self.blocks):
            tok, kv = blk(tok, rope, mask, None if cache is None else cache[i])
            new_cache.append(kv)
        tok = self.norm(tok).reshape(b, t, tps, cfg.width)[:, :, 2:]
        out = self.out(tok)
        return (out + frames if cfg.residual else out), new_cache

    def _positions(self, t0: int, t: int, device: torch.device) -> tuple[torch.Tensor | None, Rope]:
        """The attention mask (None for one step) and rotary tables of steps t0 .. t0+t-1 against the cache of steps < t0.

        They depend on the step counts alone, and a training step asks for the same few twice per batch, so they are
        built once per (t0, t, device) and kept (a handful of small tensors, never part of the autograd graph).
        """
        key = (t0, t, str(device))
        if key not in self._position_cache:
            cfg = self.cfg
            tps = cfg.tokens_per_step
            # new tokens see every cached (earlier) token and, block-causally, each other
            mask = block_causal_mask(t, tps, device=device)
            if t0:
                mask = torch.cat([torch.ones(t * tps, t0 * tps, dtype=torch.bool, device=device), mask], dim=1)
            if t == 1:
                mask = None  # one step attends to everything before and within it
            pos, spatial = token_positions(t0 + t, cfg.grid, device=device)
            rope = rope_tables(
                pos[:, :, t0 * tps :], cfg.width // cfg.heads, spatial=spatial[t0 * tps :], theta=cfg.rope_theta
            )
            self._position_cache[key] = (mask, rope)
        return self._position_cache[key]

    def n_parameters(self) -> int:
        return sum(p.numel() for p in self.parameters())
