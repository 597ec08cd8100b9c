"""The statistics every layer shares (models, study, paper): separation, correlation, recovery, error, miss, and the
swap condition's derangement.

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
* A share of successes is tested against one half by the exact binomial test, with the
  exact (Clopper-Pearson) two-sided interval of the proportion.
* A difference in means of paired per-object samples gets a percentile interval from a
  bootstrap that resamples objects (pairs kept together).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
    # imported on use, as binomtest below: scikit-learn and scipy.stats take a second or more each to import, and
    # most commands that import this module call neither
    from sklearn.metrics import roc_auc_score

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


@dataclass(frozen=True)
class BinomialShare:
    """``count`` successes of ``n`` tested against a share of one half: ``p``, the exact binomial
    test's p-value (``alternative`` two-sided, greater or less); ``low`` and ``high``, the exact
    (Clopper-Pearson) two-sided interval of the share at ``level``, as fractions."""

    count: int
    n: int
    alternative: str
    p: float
    low: float
    high: float


def binomial_share(count: int, n: int, *, alternative: str = "two-sided", level: float = 0.95) -> BinomialShare:
    """Exact binomial test of ``count`` of ``n`` against 1/2 and the share's exact interval.

    The interval is the two-sided one whatever the test's alternative, so a one-sided
    test is reported with the same kind of interval as a two-sided one.
    """
    if n < 1 or not 0 <= count <= n:
        raise ValueError(f"a binomial share needs 0 <= count <= n and n >= 1, got {count} of {n}")
    from scipy.stats import binomtest

    p = binomtest(int(count), int(n), 0.5, alternative=alternative).pvalue
    ci = binomtest(int(count), int(n), 0.5).proportion_ci(confidence_level=level, method="exact")
    return BinomialShare(int(count), int(n), alternative, float(p), float(ci.low), float(ci.high))


@dataclass(frozen=True)
class PairedDifference:
    """Mean of a - b over paired samples (``diff``) and its bootstrap percentile interval."""

    diff: float
    low: float
    high: float


def paired_bootstrap_difference(a, b, *, resamples: int, seed: int, level: float = 0.95) -> PairedDifference:
    """Mean difference of paired samples ``a`` and ``b`` (N,) with a percentile bootstrap interval.

    Each of ``resamples`` draws picks N pairs with replacement (numpy ``default_rng(seed)``),
    so the interval is the same for the same inputs and seed. No resamples: NaN interval.
    """
    a = np.asarray(a, dtype=float).ravel()
    b = np.asarray(b, dtype=float).ravel()
    if a.size != b.size or a.size < 1:
        raise ValueError("a paired difference needs two equal-length samples of at least 1")
    d = a - b
    if resamples < 1:
        return PairedDifference(float(d.mean()), float("nan"), float("nan"))
    index = np.random.default_rng(seed).integers(0, d.size, size=(resamples, d.size))
    tail = 100.0 * (1.0 - level) / 2.0
    low, high = np.percentile(d[index].mean(axis=1), [tail, 100.0 - tail])
    return PairedDifference(float(d.mean()), float(low), float(high))


def derangement(n: int, seed: int) -> np.ndarray:
    """A permutation with no fixed point: object i takes object partner[i]'s calibration.

    A random cyclic order (from ``seed``), each object paired with the next one in it.
    """
    if n < 2:
        raise ValueError("a swap needs at least 2 objects")
    order = np.random.default_rng(seed).permutation(n)
    partner = np.empty(n, dtype=np.int64)
    partner[order] = np.roll(order, -1)
    return partner
