"""Rules that choose one of several candidate rollout sets per object (Sections 4 and 5).

Each object has C candidate sets (N, C, K). A rule returns the chosen candidate's
index per object; consensus instead builds a synthetic per-speed median set.
"""

from __future__ import annotations

import numpy as np


def select_first(n: int) -> np.ndarray:
    """The first candidate of every object (candidates are shuffled, so a random one)."""
    return np.zeros(n, dtype=np.int64)


def select_lowest(scores) -> np.ndarray:
    """The candidate with the lowest score per object: scores (N, C) -> (N,) indices."""
    s = np.asarray(scores, dtype=float)
    if not np.all(np.isfinite(s)):
        raise ValueError("selection scores must be finite")
    return np.argmin(s, axis=1)


def consensus(candidates) -> np.ndarray:
    """Per-speed median of the candidates: (N, C, K) -> (N, K)."""
    return np.median(np.asarray(candidates, dtype=float), axis=1)


def select_medoid(candidates, floor: float) -> np.ndarray:
    """The medoid candidate per object: least summed Euclidean distance in log displacement
    (over the K speeds) to the object's other candidates, as geometry-guided
    self-consistency takes the medoid of sampled action chunks. Ties go to the lower index."""
    logc = np.log(np.maximum(np.asarray(candidates, dtype=float), floor))
    diff = logc[:, :, None, :] - logc[:, None, :, :]
    dist = np.sqrt((diff * diff).sum(axis=-1)).sum(axis=2)
    return np.argmin(dist, axis=1)


def take(candidates, chosen) -> np.ndarray:
    """The chosen candidate's rollouts per object: (N, C, K), (N,) -> (N, K)."""
    c = np.asarray(candidates)
    return c[np.arange(c.shape[0]), np.asarray(chosen)]
