"""The object-blind baseline: the typical log slide at a speed, fit to training pushes."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imply.models.object_blind import fit_typical_slide, typical_slide_of_clips


def test_typical_slide_is_the_geometric_mean_at_each_speed():
    rng = np.random.default_rng(0)
    v = rng.uniform(0.15, 1.05, 4000)
    log_d = 2.0 * np.log(v) - 2.5 + 0.1 * np.log(v) ** 2 + rng.normal(0.0, 0.4, v.size)  # object spread
    typical = fit_typical_slide(v, np.exp(log_d))
    grid = np.array([0.25, 0.55, 0.85])
    truth = 2.0 * np.log(grid) - 2.5 + 0.1 * np.log(grid) ** 2
    assert np.allclose(typical.log_slide(grid), truth, atol=0.05)
    assert np.allclose(typical.slide(grid), np.exp(typical.log_slide(grid)))


def test_clips_with_a_failed_push_or_no_slide_are_left_out():
    meta = pd.DataFrame(
        {
            "speed": [0.3, 0.5, 0.7, 0.9, 1.0, 0.4],
            "displacement": [0.02, 0.05, 0.1, 0.16, 0.2, 0.0],
            "ok": [1, 1, 1, 1, 1, 1],
        }
    )
    with_zero = typical_slide_of_clips(meta)
    assert np.isfinite(with_zero.log_slide([0.5])).all()
    bad = meta.assign(ok=[1, 1, 0, 0, 1, 1])  # three pushes left: too few for a cubic
    with pytest.raises(ValueError, match="more than 3 pushes"):
        typical_slide_of_clips(bad)
