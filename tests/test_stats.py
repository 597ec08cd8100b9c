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
