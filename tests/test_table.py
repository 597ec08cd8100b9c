"""Building, checking, saving and interpolating the push table."""

from __future__ import annotations

import numpy as np
import pytest

from imply.table import OutOfRangeError, PushTable, TableCheckConfig, TableError, check_nodes, check_table


def test_tiny_table_shape_and_metadata(tiny_table):
    t = tiny_table
    assert t.log_d.shape == (7, 6, 6)
    assert np.all(np.isfinite(t.log_d))
    assert np.all(np.diff(t.log_d, axis=0) > 0)
    assert np.all(np.diff(t.log_d, axis=2) < 0)
    assert t.meta["mujoco_version"]
    assert len(t.meta["config_digest"]) == 16
    assert t.meta["stepping"]["push_step_s"] == pytest.approx(t.meta["scene"]["timestep"] / 8)
    assert t.meta["stepping"]["substeps_total"] > 0


def test_full_table_every_cell(full_table):
    """The default 19 x 25 x 21 table: finite, d up with v and down with mu nearly everywhere."""
    t = full_table
    assert t.log_d.shape == (19, 25, 21)
    assert np.all(np.isfinite(t.log_d))
    # the converged scene is not monotone in speed for a few light, rough boxes at low
    # speed (the box rocks on its edges while pushed; the reference shows the same)
    mono = t.meta["monotonicity"]
    assert mono["cells_decreasing_in_speed"] < 0.01 * t.log_d.size
    assert mono["largest_decrease_in_speed"] < 0.1
    assert mono["cells_increasing_in_friction"] == 0
    d = np.exp(t.log_d)
    assert d.min() < 0.02 and d.max() > 0.3  # slides from about a centimetre to tens of cm


def test_the_stored_default_table_is_what_the_builder_gives(full_table, scene):
    """tests/stored/default_table.npz against the simulator, on its 8 corners and 40 random cells: the same log d
    to 1e-6 (the builder is deterministic; the margin is for another CPU's last bits), so the tests that read the
    stored table read what ``build_table`` writes today."""
    from imply.sim import simulate_pushes

    nodes = check_nodes(full_table.log_d.shape, 48, seed=20261129)
    i, j, k = np.unravel_index(nodes, full_table.log_d.shape)
    run = simulate_pushes(full_table.speeds[i], full_table.masses[j], full_table.frictions[k], scene=scene, nthread=1)
    assert run.ok.all()
    np.testing.assert_allclose(np.log(run.displacement), full_table.log_d[i, j, k], rtol=0, atol=1e-6)


def test_check_nodes_take_the_corners_first_then_distinct_random_nodes():
    nodes = check_nodes((19, 25, 21), 200, seed=3)
    assert nodes.size == 200 and np.unique(nodes).size == 200
    corners = {np.ravel_multi_index((i, j, k), (19, 25, 21)) for i in (0, 18) for j in (0, 24) for k in (0, 20)}
    assert corners == set(nodes[:8].tolist())
    np.testing.assert_array_equal(nodes, check_nodes((19, 25, 21), 200, seed=3))
    assert check_nodes((4, 4, 4), 1000, seed=0).size == 64


def test_table_converges_to_a_much_finer_reference(tiny_table):
    """The table's stepping against the same scene stepped uniformly 32 times finer.

    The 8 corners of the range plus low-speed cells, where the box rocks on its edges
    while pushed and the stepping is most tested. The reference's own error (about its
    difference from a run at twice its step) is small beside the tolerance.
    """
    error = check_table(tiny_table, TableCheckConfig(cells=12, seed=1, reference_substeps=32), nthread=2)
    assert error["cells"] == 12
    assert error["reference_error_max"] < 0.003
    assert error["max_abs_log_d"] <= 0.005
    assert error["rms_log_d"] <= 0.002


def test_the_check_fails_a_table_stepped_too_coarsely(scene):
    """The check can fail: the same scene pushed at the full 1 ms step is far off."""
    from dataclasses import replace

    from imply.table import TableGrid, build_table

    coarse = replace(scene, push_substeps=1, slow_push_speed=0.0, release_window=0.0, slide_steps=0)
    grid = TableGrid(
        speed_min=0.3,
        speed_max=1.05,
        n_speeds=4,
        mass_min=0.2,
        mass_max=2.0,
        n_masses=4,
        friction_min=0.1,
        friction_max=0.6,
        n_frictions=4,
    )
    error = check_table(
        build_table(coarse, grid, nthread=2), TableCheckConfig(cells=8, reference_substeps=32), nthread=2
    )
    assert error["max_abs_log_d"] > 0.01


def test_save_load_round_trip(tiny_table, tmp_path):
    path = tmp_path / "t.npz"
    tiny_table.save(path)
    loaded = PushTable.load(path)
    np.testing.assert_array_equal(loaded.log_d, tiny_table.log_d)
    assert loaded.meta == tiny_table.meta
    assert sorted(np.load(path).files) == ["frictions", "log_d", "masses", "meta", "speeds"]


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
