"""Building, checking, saving and interpolating the push table."""

from __future__ import annotations

import numpy as np
import pytest

from imply.table import OutOfRangeError, PushTable, TableError, monotone_projection


def test_tiny_table_shape_and_monotonicity(tiny_table):
    t = tiny_table
    assert t.log_d.shape == (7, 6, 6)
    assert np.all(np.isfinite(t.log_d))
    assert np.all(np.diff(t.log_d, axis=0) >= 0)
    assert np.all(np.diff(t.log_d, axis=2) <= 0)
    assert t.meta["mujoco_version"]
    assert len(t.meta["config_digest"]) == 16
    assert t.meta["monotone_projection"]["max_abs_change"] < 0.05


def test_full_table_every_cell(full_table):
    """The default 19 x 25 x 21 table: finite, d up with v, down with mu, little smoothing."""
    t = full_table
    assert t.log_d.shape == (19, 25, 21)
    assert np.all(np.isfinite(t.log_d)) and np.all(np.isfinite(t.log_d_raw))
    assert np.all(np.diff(t.log_d, axis=0) >= 0)
    assert np.all(np.diff(t.log_d, axis=2) <= 0)
    # the projection only removes solver jitter: raw cells already monotone almost everywhere
    raw = t.log_d_raw
    violations = (np.diff(raw, axis=0) <= 0).mean() + (np.diff(raw, axis=2) >= 0).mean()
    assert violations < 0.03
    assert np.abs(t.log_d - raw).max() < 0.05
    d = np.exp(t.log_d)
    assert d.min() < 0.02 and d.max() > 0.3  # slides from about a centimetre to tens of cm


def test_save_load_round_trip(tiny_table, tmp_path):
    path = tmp_path / "t.npz"
    tiny_table.save(path)
    loaded = PushTable.load(path)
    np.testing.assert_array_equal(loaded.log_d, tiny_table.log_d)
    assert loaded.meta == tiny_table.meta
    assert sorted(np.load(path).files) == ["frictions", "log_d", "log_d_raw", "masses", "meta", "speeds"]


def test_load_refuses_bad_files(tmp_path):
    with pytest.raises(TableError, match="does not exist"):
        PushTable.load(tmp_path / "missing.npz")
    junk = tmp_path / "junk.npz"
    junk.write_text("not a zip")
    with pytest.raises(TableError, match="cannot read"):
        PushTable.load(junk)
    wrong = tmp_path / "wrong.npz"
    np.savez(wrong, speeds=np.arange(5.0))
    with pytest.raises(TableError, match="missing array"):
        PushTable.load(wrong)


def test_interpolation_hits_nodes_and_refuses_extrapolation(tiny_table):
    t = tiny_table
    i, j, k = 3, 2, 4
    got = t.log_displacement(t.speeds[i], t.masses[j], t.frictions[k])
    assert got == pytest.approx(t.log_d[i, j, k], abs=1e-9)
    with pytest.raises(OutOfRangeError, match="speed 2"):
        t.log_displacement(2.0, 0.5, 0.3)
    with pytest.raises(OutOfRangeError, match="mass"):
        t.log_displacement(0.5, 5.0, 0.3)
    with pytest.raises(OutOfRangeError, match="friction"):
        t.log_displacement(0.5, 0.5, 0.01)


def test_monotone_projection_fixes_noise():
    rng = np.random.default_rng(0)
    v = np.linspace(0, 1, 8)[:, None, None]
    mu = np.linspace(0, 1, 6)[None, None, :]
    noisy = v - mu + 0.02 * rng.standard_normal((8, 3, 6))
    out, passes = monotone_projection(noisy)
    assert np.all(np.diff(out, axis=0) >= -1e-12)
    assert np.all(np.diff(out, axis=2) <= 1e-12)
    assert passes >= 1
    clean = v - mu + np.zeros((8, 3, 6))
    np.testing.assert_array_equal(monotone_projection(clean)[0], clean)
