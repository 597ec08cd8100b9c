"""JEPA pretraining of the CPU default encoder on frames of the ``pretrain`` clips.

Objective (as in V-JEPA, on single frames duplicated into a tubelet, the way the
encoder is used downstream): hide a block of patch columns, encode the visible
patches with the context encoder, predict the hidden patches' tokens with
:class:`imply.models.masked_predictor.MaskedPredictor`, and regress them (L1) onto the
layer-normed tokens of a target encoder that is an exponential moving average of the
context encoder (momentum ramped from ``ema[0]`` to ``ema[1]``). AdamW with linear
warmup and cosine decay. The frozen target encoder is what gets saved and used.

Config ``encoder.pretrain``; everything is seeded, and torch runs on a fixed number of
threads, so the same config gives the same weights on the same machine.
"""

from __future__ import annotations

import copy
import logging
import math
import time
from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import torch
import torch.nn.functional as F
from tqdm.auto import tqdm

from imply.models.config import ViTConfig
from imply.models.masked_predictor import MaskedPredictor
from imply.models.modules import grid_positions
from imply.models.vision_transformer import VisionTransformer, preprocess
from imply.options import Config, option

log = logging.getLogger("imply.encoder")


@dataclass(frozen=True, kw_only=True)
class PretrainConfig(Config):
    """Config section ``encoder.pretrain``: the CPU default encoder's JEPA pretraining."""

    config_key: ClassVar[str] = "encoder.pretrain"

    seed: int = option(0, doc="seed of the weights and the masks", minimum=0)
    steps: int = option(800, doc="optimiser steps", minimum=1)
    batch_size: int = option(64, doc="frames per step", minimum=1)
    lr: float = option(1.0e-3, doc="peak learning rate", exclusive_minimum=0)
    min_lr: float = option(1.0e-5, doc="learning rate at the end of the cosine decay", minimum=0)
    warmup: int = option(50, doc="warmup steps", minimum=0)
    weight_decay: float = option(0.04, doc="AdamW weight decay", minimum=0)
    ema: tuple[float, float] = option(
        (0.996, 1.0), doc="target encoder EMA momentum, first and last step", items={"minimum": 0, "maximum": 1}
    )
    mask_cols: tuple[int, int] = option((2, 4), doc="masked patch columns, fewest and most", items={"minimum": 1})
    pred_dim: int = option(48, doc="the masked predictor's width", minimum=4)
    pred_depth: int = option(2, doc="the masked predictor's blocks", minimum=1)
    pred_heads: int = option(4, doc="the masked predictor's heads", minimum=1)


def _lr_at(step: int, cfg: PretrainConfig) -> float:
    if step < cfg.warmup:
        return cfg.lr * (step + 1) / cfg.warmup
    frac = (step - cfg.warmup) / max(1, cfg.steps - cfg.warmup)
    return cfg.min_lr + 0.5 * (cfg.lr - cfg.min_lr) * (1 + math.cos(math.pi * frac))


def pretrain_encoder(
    frames: np.ndarray, arch: ViTConfig, cfg: PretrainConfig, *, progress: bool = True
) -> tuple[VisionTransformer, dict[str, Any]]:
    """Pretrain on uint8 frames (N, H, W, 3); returns the frozen target encoder and a history."""

    torch.manual_seed(cfg.seed)
    rng = np.random.default_rng(cfg.seed)
    h, w = frames.shape[1:3]
    if h % arch.patch_size or w % arch.patch_size:
        raise ValueError(f"frame size {h}x{w} is not a multiple of the patch size {arch.patch_size}")
    n_rows, n_cols = h // arch.patch_size, w // arch.patch_size
    lo, hi = cfg.mask_cols
    if not 1 <= lo <= hi < n_cols:
        raise ValueError(f"encoder.pretrain.mask_cols must lie in 1..{n_cols - 1}")

    context = VisionTransformer(arch)
    target = copy.deepcopy(context)
    for p in target.parameters():
        p.requires_grad_(False)
    predictor = MaskedPredictor(arch.embed_dim, cfg.pred_dim, cfg.pred_depth, cfg.pred_heads)
    params = list(context.parameters()) + list(predictor.parameters())
    opt = torch.optim.AdamW(params, lr=cfg.lr, weight_decay=cfg.weight_decay)
    pos_all = grid_positions(1, n_rows, n_cols)  # (3, n_tokens)
    col_of = torch.arange(n_rows * n_cols) % n_cols

    losses = []
    t0 = time.perf_counter()
    bar = tqdm(range(cfg.steps), desc="pretrain encoder", disable=not progress, mininterval=2.0)
    for step in bar:
        idx = rng.integers(0, len(frames), cfg.batch_size)
        x = preprocess(frames[np.sort(idx)], (h, w), arch.tubelet_size)
        # a block of `width` patch columns (all rows) is hidden; width fixed within a batch
        width = int(rng.integers(lo, hi + 1))
        start = torch.as_tensor(rng.integers(0, n_cols - width + 1, cfg.batch_size))
        hidden = (col_of[None, :] >= start[:, None]) & (col_of[None, :] < start[:, None] + width)
        order = torch.argsort(hidden.int(), dim=1, stable=True)  # visible first, then hidden
        n_vis = n_rows * (n_cols - width)
        keep, tgt = order[:, :n_vis], order[:, n_vis:]

        with torch.no_grad():
            full = target(x)
            full = F.layer_norm(full, (full.shape[-1],))
            y = torch.gather(full, 1, tgt.unsqueeze(-1).expand(-1, -1, full.shape[-1]))
        ctx = context(x, keep=keep)
        pos = pos_all.unsqueeze(0).expand(cfg.batch_size, -1, -1)
        ctx_pos = torch.gather(pos, 2, keep.unsqueeze(1).expand(-1, 3, -1))
        tgt_pos = torch.gather(pos, 2, tgt.unsqueeze(1).expand(-1, 3, -1))
        pred = predictor(ctx, ctx_pos, tgt_pos)
        loss = F.l1_loss(pred, y)

        for g in opt.param_groups:
            g["lr"] = _lr_at(step, cfg)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        torch.nn.utils.clip_grad_norm_(params, 1.0)
        opt.step()
        m = cfg.ema[0] + (cfg.ema[1] - cfg.ema[0]) * step / max(1, cfg.steps - 1)
        with torch.no_grad():
            for pt, pc in zip(target.parameters(), context.parameters(), strict=True):
                pt.mul_(m).add_(pc.detach(), alpha=1 - m)
        losses.append(float(loss.detach()))
        if step % 50 == 0:
            bar.set_postfix(loss=f"{np.mean(losses[-50:]):.4f}")
    bar.close()
    dt = time.perf_counter() - t0
    log.info(
        "pretrained %d steps x %d frames in %.1f s; loss %.4f -> %.4f",
        cfg.steps,
        cfg.batch_size,
        dt,
        float(np.mean(losses[:50])),
        float(np.mean(losses[-50:])),
    )
    target.eval()
    return target, {"loss": losses, "seconds": dt}
