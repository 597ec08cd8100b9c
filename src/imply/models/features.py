"""Cached encoder features: one split's tokens with its clip metadata, and the one token pooling.

Inputs are the clips stage's files (formats in :mod:`imply.data.clips` and
:mod:`imply.models.encoder`): ``results/clips/<split>.csv`` (one row per clip) and
``results/features/<split>.npz`` (``tokens`` float16 (n_clips, 8, n_patches, dim)),
read together by :func:`load_feature_split`.

Pooling (:func:`pool_tokens`) average-pools a frame's patch grid to a coarser one. It
acts at two places, under two config keys, because they are two choices: the encoder
pools before caching (``encoder.pool_grid``: what every reader of the features sees,
the ridge readout included; needed for ViT-g, whose tokens are too large to cache
whole), and the predictor's inputs are pooled from the cache (``model.token_grid``:
what the predictor carries from step to step, :meth:`FeatureSplit.pooled`).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

POOL_CHUNK = 256  # clips pooled at once: the float32 copy of a whole split would double its memory


@dataclass(frozen=True)
class FeatureSplit:
    """A split's cached encoder tokens and clip metadata, rows aligned."""

    tokens: np.ndarray  # (n_clips, n_frames, n_patches, dim)
    meta: pd.DataFrame
    grid: tuple[int, int]

    @property
    def n_frames(self) -> int:
        return self.tokens.shape[1]

    def pooled(self, grid: tuple[int, int] | None) -> FeatureSplit:
        """The split with its tokens pooled to ``grid`` (:func:`pool_tokens`); None or its own grid keeps it."""
        if grid is None or tuple(grid) == tuple(self.grid):
            return self
        to = (int(grid[0]), int(grid[1]))
        return FeatureSplit(tokens=pool_tokens(self.tokens, self.grid, to), meta=self.meta, grid=to)


def pool_tokens(tokens: np.ndarray, grid: tuple[int, int], to: tuple[int, int]) -> np.ndarray:
    """Patch tokens (n_clips, n_frames, rows*cols, D) on ``grid`` average-pooled to ``to`` (rows, columns).

    Each pooled token is the mean (in float32) of a block of the patches, so every side
    of ``grid`` must be a multiple of the pooled one; the result keeps the input's dtype.
    The box moves along the image's width, so a one-row grid keeps where it is and drops
    what the predictor does not need to carry from step to step (the table's rows above
    and below it).
    """
    (gh, gw), (th, tw) = (int(grid[0]), int(grid[1])), (int(to[0]), int(to[1]))
    if th < 1 or tw < 1 or gh % th or gw % tw:
        raise ValueError(f"token grid {th}x{tw} does not divide the encoder's {gh}x{gw} patch grid")
    n, t, _, d = tokens.shape
    pooled = np.empty((n, t, th * tw, d), dtype=tokens.dtype)
    for lo in range(0, n, POOL_CHUNK):
        block = tokens[lo : lo + POOL_CHUNK].astype(np.float32).reshape(-1, t, th, gh // th, tw, gw // tw, d)
        pooled[lo : lo + POOL_CHUNK] = block.mean(axis=(3, 5)).reshape(-1, t, th * tw, d)
    return pooled


def load_feature_split(features: str | Path, metadata: str | Path) -> FeatureSplit:
    """Read ``results/features/<split>.npz`` and ``results/clips/<split>.csv``."""
    meta = pd.read_csv(metadata, dtype={"object_id": str, "role": str, "split": str})
    with np.load(features) as z:
        tokens = z["tokens"]
        clip_id = z["clip_id"]
        grid = tuple(int(g) for g in z["grid"]) if "grid" in z else _square_grid(tokens.shape[2])
    if not np.array_equal(clip_id, meta["clip_id"].to_numpy()):
        raise ValueError(f"{features} and {metadata} list different clips")
    if grid[0] * grid[1] != tokens.shape[2]:
        raise ValueError(f"{features}: grid {grid} does not match {tokens.shape[2]} patches")
    return FeatureSplit(tokens=tokens, meta=meta, grid=grid)


def _square_grid(p: int) -> tuple[int, int]:
    g = int(round(p**0.5))
    if g * g != p:
        raise ValueError(f"{p} patches and no grid given")
    return (g, g)
