"""Displacement readouts: the ridge from encoder features and the frame difference from pixels."""

from __future__ import annotations

import numpy as np
import pytest

from imply.readout import FrameDiffReadout, ReadoutConfig, RidgeReadout, frame_diff_shift, load_readout, r2_log


def test_ridge_readout_recovers_a_linear_map(tmp_path):
    rng = np.random.default_rng(0)
    x = rng.normal(size=(400, 4, 8))
    w = rng.normal(size=32)
    log_d = x.reshape(400, -1) @ w * 0.05 - 2.5
    d = np.exp(log_d + rng.normal(scale=0.01, size=400))
    r = RidgeReadout.fit(x[:300], d[:300])
    assert r2_log(d[300:], r.predict(x[300:])) > 0.95
    r.save(tmp_path / "ridge.npz")
    back = load_readout(tmp_path / "ridge.npz")
    np.testing.assert_allclose(back.predict(x[300:]), r.predict(x[300:]))
    np.testing.assert_allclose(back.predict(x[300:].reshape(100, -1)), r.predict(x[300:]))
    with pytest.raises(ValueError, match="do not match"):
        back.predict(x[:, :2])
    # features that carry nothing read nothing
    noise = RidgeReadout.fit(rng.normal(size=(300, 4, 8)), d[:300])
    assert r2_log(d[300:], noise.predict(rng.normal(size=(100, 4, 8)))) < 0.2


def test_frame_difference_reads_a_moving_square():
    first = np.full((4, 20, 60, 3), 120, dtype=np.uint8)
    last = first.copy()
    for i, s in enumerate([0, 3, 10, 30]):
        first[i, 5:13, 4:12] = (200, 80, 50)
        last[i, 5:13, 4 + s : 12 + s] = (200, 80, 50)
    np.testing.assert_allclose(frame_diff_shift(first, last), [0, 3, 10, 30], atol=1e-9)
    clips = np.stack([first, last], axis=1)
    fd = FrameDiffReadout.fit(clips, np.array([0.001, 0.03, 0.1, 0.3]))
    np.testing.assert_allclose(fd.slope, 0.01, rtol=0.05)


def test_readout_settings():
    cfg = ReadoutConfig.from_dict({"log10_alpha_min": -2, "log10_alpha_max": 5, "n_alphas": 29})
    np.testing.assert_array_equal(cfg.alphas(), np.logspace(-2, 5, 29))
    with pytest.raises(ValueError, match="log10_alpha_min"):
        ReadoutConfig.from_dict({"log10_alpha_min": 3, "log10_alpha_max": 1})
