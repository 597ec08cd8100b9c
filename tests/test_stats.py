"""The shared statistics (imply.stats)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imply import stats


def test_auroc_known_values():
    assert stats.auroc([0, 1, 2], [3, 4]) == 1.0
    assert stats.auroc([3, 4], [0, 1]) == 0.0
    assert stats.auroc([1, 1], [1, 1]) == 0.5  # ties count one half
    assert stats.auroc([0, 2], [1, 3]) == 0.75
    with pytest.raises(ValueError):
        stats.auroc([], [1.0])
    with pytest.raises(ValueError):
        stats.auroc([np.nan], [1.0])


def test_pearson_r2_and_log_error():
    x = np.arange(10.0)
    assert stats.pearson(x, 2 * x + 1) == pytest.approx(1.0)
    assert stats.pearson(x, -x) == pytest.approx(-1.0)
    assert math.isnan(stats.pearson(x, np.zeros(10)))  # constant side: undefined, not 0
    assert stats.r_squared(x, x) == 1.0
    assert stats.r_squared(x, np.full(10, x.mean())) == pytest.approx(0.0)
    # a biased prediction has a lower R^2 than its correlation would suggest (identity line)
    assert stats.r_squared(x, x + 3) < 0.5
    true = np.array([[0.1, 0.2]])
    assert stats.log_error(true, true, 1e-4)[0] == 0.0
    assert stats.log_error(true * np.e, true, 1e-4)[0] == pytest.approx(1.0)
    # below the floor, predictions are clamped like the score clamps them
    assert stats.log_error(np.zeros((1, 2)), np.full((1, 2), 1e-3), 1e-4)[0] == pytest.approx(np.log(10))
    miss = stats.miss_mm([0.105, 0.2], [0.1, 0.1])
    np.testing.assert_allclose(miss, [5.0, 100.0])
    assert stats.share_within(miss, 10) == 0.5


def _upper_tail(k: int, n: int, p: float) -> float:
    """P(X >= k) for X ~ Binomial(n, p), summed term by term."""
    return sum(math.comb(n, j) * p**j * (1 - p) ** (n - j) for j in range(k, n + 1))


def _bisect(f, target: float) -> float:
    """The p in (0, 1) where the increasing f(p) crosses target."""
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if f(mid) < target else (lo, mid)
    return (lo + hi) / 2


def test_binomial_share_against_a_hand_computation():
    # 169 of 300: the upper tail at one half, doubled (the null is symmetric), is the two-sided p
    tail = _upper_tail(169, 300, 0.5)
    share = stats.binomial_share(169, 300)
    assert share.p == pytest.approx(2 * tail, rel=1e-9) and share.p == pytest.approx(0.0327, abs=5e-4)
    assert share.p < 0.05  # "self at chance" within 10 points of 50% would have passed this one
    # Clopper-Pearson: the shares at which the count is just in the 2.5% upper / lower tail
    low = _bisect(lambda p: _upper_tail(169, 300, p), 0.025)
    high = _bisect(lambda p: _upper_tail(170, 300, p), 1 - 0.025)  # where P(X <= 169) falls to 0.025
    assert (share.low, share.high) == (pytest.approx(low, abs=1e-9), pytest.approx(high, abs=1e-9))
    assert share.low < 169 / 300 < share.high and share.low > 0.5
    greater = stats.binomial_share(169, 300, alternative="greater")
    assert greater.p == pytest.approx(tail, rel=1e-9)
    assert (greater.low, greater.high) == (share.low, share.high)  # the interval is two-sided either way
    assert stats.binomial_share(150, 300).p == pytest.approx(1.0)
    # one-sided "greater" on a count below half: P(X >= 131) = 1 - P(X >= 170) by symmetry
    assert stats.binomial_share(131, 300, alternative="greater").p == pytest.approx(1 - _upper_tail(170, 300, 0.5))
    with pytest.raises(ValueError):
        stats.binomial_share(4, 3)
    with pytest.raises(ValueError):
        stats.binomial_share(0, 0)


def test_paired_bootstrap_difference_is_deterministic_and_pairs_objects():
    rng = np.random.default_rng(0)
    b = rng.normal(0.4, 0.3, 200)
    a = b + 0.05 + rng.normal(0, 0.02, 200)  # paired: the spread of b cancels in a - b
    d = stats.paired_bootstrap_difference(a, b, resamples=500, seed=7)
    assert d.diff == pytest.approx(np.mean(a - b))
    assert d.low < d.diff < d.high and d.low > 0.04 and d.high < 0.06
    assert d == stats.paired_bootstrap_difference(a, b, resamples=500, seed=7)
    assert d != stats.paired_bootstrap_difference(a, b, resamples=500, seed=8)
    # resampling objects, not the two samples apart: an unpaired interval would be about 15 times wider
    assert d.high - d.low < 4 * 1.96 * 0.02 / np.sqrt(200)
    same = stats.paired_bootstrap_difference(b + 0.1, b, resamples=100, seed=0)
    assert same.low == pytest.approx(0.1) and same.high == pytest.approx(0.1)
    assert math.isnan(stats.paired_bootstrap_difference(a, b, resamples=0, seed=0).low)
    with pytest.raises(ValueError):
        stats.paired_bootstrap_difference(a, b[:-1], resamples=10, seed=0)
