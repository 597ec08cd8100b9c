"""The selection rules shared by the study's sections."""

from __future__ import annotations

import numpy as np
import pytest

from imply.study import selection_rules


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
