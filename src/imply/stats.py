"""The statistics every layer shares (models, study, paper): separation, correlation, recovery, error, miss.

It imports nothing of :mod:`imply` beyond itself, so a model's validation, the study's
scoring and the paper's figures compute a correlation the same way.

Conventions:

* Scores are "higher = worse" (disagreements), so AUROC(neg, pos) is the probability
  that a stand-in's set (positive) scores above an oracle set (negative), ties 1/2.
* Log error of a rollout set: RMS over its K speeds of log(predicted) - log(true),
  predictions clamped below at the readout floor like the score does.
* R^2 is the coefficient of determination of predictions against the truth
  (1 - SS_res / SS_tot, identity line, not a refitted regression).
* The miss of a chosen rollout is |chosen displacement - true displacement| at one
  query speed, in mm.
"""

from __future__ import annotations

import numpy as np
from sklearn.metrics import roc_auc_score


def auroc(negatives, positives) -> float:
    """AUROC of separating positives (scored higher) from negatives; NaN scores are errors."""
    neg = np.asarray(negatives, dtype=float).ravel()
    pos = np.asarray(positives, dtype=float).ravel()
    if neg.size == 0 or pos.size == 0:
        raise ValueError("AUROC needs at least one negative and one positive")
    scores = np.concatenate([neg, pos])
    if not np.all(np.isfinite(scores)):
        raise ValueError("AUROC scores must be finite")
    labels = np.concatenate([np.zeros(neg.size), np.ones(pos.size)])
    return float(roc_auc_score(labels, scores))


def pearson(x, y) -> float:
    """Pearson correlation; NaN when either side is constant (e.g. the oracle's zero error)."""
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    if x.size != y.size or x.size < 2:
        raise ValueError("correlation needs two equal-length samples of at least 2")
    xc, yc = x - x.mean(), y - y.mean()
    den = np.sqrt((xc * xc).sum() * (yc * yc).sum())
    if not den > 0:
        return float("nan")
    return float((xc * yc).sum() / den)


def r_squared(true, pred) -> float:
    """Coefficient of determination of ``pred`` against ``true`` (identity line)."""
    t = np.asarray(true, dtype=float).ravel()
    p = np.asarray(pred, dtype=float).ravel()
    ss_tot = ((t - t.mean()) ** 2).sum()
    if not ss_tot > 0:
        return float("nan")
    return float(1.0 - ((t - p) ** 2).sum() / ss_tot)


def log_error(pred, true, floor: float) -> np.ndarray:
    """RMS over the last axis (the K speeds) of log(max(pred, floor)) - log(max(true, floor))."""
    p = np.log(np.maximum(np.asarray(pred, dtype=float), floor))
    t = np.log(np.maximum(np.asarray(true, dtype=float), floor))
    return np.sqrt(np.mean((p - t) ** 2, axis=-1))


def miss_mm(chosen_displacement, true_displacement) -> np.ndarray:
    """Absolute miss in millimetres (inputs in metres)."""
    return 1000.0 * np.abs(np.asarray(chosen_displacement, float) - np.asarray(true_displacement, float))


def share_within(miss, limit_mm: float) -> float:
    """Share of objects whose miss is at most ``limit_mm``."""
    miss = np.asarray(miss, dtype=float)
    return float(np.mean(miss <= limit_mm))
