"""Metrics and selection rules shared by the study's sections."""

from __future__ import annotations

import math

import numpy as np
import pytest

from imply.study import metrics, selection_rules


def test_auroc_known_values():
    assert metrics.auroc([0, 1, 2], [3, 4]) == 1.0
    assert metrics.auroc([3, 4], [0, 1]) == 0.0
    assert metrics.auroc([1, 1], [1, 1]) == 0.5  # ties count one half
    assert metrics.auroc([0, 2], [1, 3]) == 0.75
    with pytest.raises(ValueError):
        metrics.auroc([], [1.0])
    with pytest.raises(ValueError):
        metrics.auroc([np.nan], [1.0])


def test_pearson_r2_and_log_error():
    x = np.arange(10.0)
    assert metrics.pearson(x, 2 * x + 1) == pytest.approx(1.0)
    assert metrics.pearson(x, -x) == pytest.approx(-1.0)
    assert math.isnan(metrics.pearson(x, np.zeros(10)))  # constant side: undefined, not 0
    assert metrics.r_squared(x, x) == 1.0
    assert metrics.r_squared(x, np.full(10, x.mean())) == pytest.approx(0.0)
    # a biased prediction has a lower R^2 than its correlation would suggest (identity line)
    assert metrics.r_squared(x, x + 3) < 0.5
    true = np.array([[0.1, 0.2]])
    assert metrics.log_error(true, true, 1e-4)[0] == 0.0
    assert metrics.log_error(true * np.e, true, 1e-4)[0] == pytest.approx(1.0)
    # below the floor, predictions are clamped like the score clamps them
    assert metrics.log_error(np.zeros((1, 2)), np.full((1, 2), 1e-3), 1e-4)[0] == pytest.approx(np.log(10))
    miss = metrics.miss_mm([0.105, 0.2], [0.1, 0.1])
    np.testing.assert_allclose(miss, [5.0, 100.0])
    assert metrics.share_within(miss, 10) == 0.5


def test_selection_rules():
    # 2 objects x 3 candidates x 2 speeds
    c = np.array(
        [
            [[0.10, 0.20], [0.11, 0.21], [0.50, 0.90]],
            [[0.01, 0.01], [0.30, 0.40], [0.31, 0.41]],
        ]
    )
    np.testing.assert_array_equal(selection_rules.select_first(2), [0, 0])
    np.testing.assert_array_equal(selection_rules.select_lowest([[3, 1, 2], [0, 5, 5]]), [1, 0])
    np.testing.assert_allclose(selection_rules.consensus(c), [[0.11, 0.21], [0.30, 0.40]])
    # the medoid sits among the agreeing pair, not on the outlier
    med = selection_rules.select_medoid(c, 1e-4)
    assert med[0] in (0, 1) and med[1] in (1, 2)
    np.testing.assert_allclose(selection_rules.take(c, [2, 0]), [[0.50, 0.90], [0.01, 0.01]])
    with pytest.raises(ValueError, match="finite"):
        selection_rules.select_lowest([[np.nan, 1.0]])
