"""The frozen evaluation suite: layout, the study's objects and frames, byte stability, refused suites, the CLI."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from imply.cli import main
from imply.data.clips import ClipsConfig, render_split, sample_objects
from imply.evaluate.suite import (
    SUITE_VERSION,
    SuiteConfig,
    SuiteError,
    build_suite,
    load_suite,
    load_truth,
    suite_table_path,
)
from imply.score import ScoreConfig
from imply.sim import SceneConfig
from imply.stats import derangement
from suite_helpers import TINY_SUITE, TINY_SUITE_CLIPS, build_tiny_suite

FILES = ("manifest.json", "suite.npz", "truth.npz", "table.npz", "README.md")


def test_layout_shapes_and_the_studys_objects(tiny_suite, tiny_table_path):
    suite = load_suite(tiny_suite)
    truth = load_truth(suite)
    n, k, t, h, w = 6, len(ScoreConfig().query_speeds), 4, 16, 64
    assert suite.n_objects == n and suite.n_speeds == k and suite.frame_shape == (h, w, 3)
    assert suite.manifest["sizes"] == {"N": n, "K": k, "C": 1, "T": t, "M": 12, "M_c": 9, "H": h, "W": w}
    assert suite.calibration_frames.shape == (n, 2, t, h, w, 3) and suite.calibration_frames.dtype == np.uint8
    assert suite.context_frames.shape == (n, k, 1, h, w, 3)
    assert suite.train_frames.shape == (12, 2, h, w, 3) and suite.check_frames.shape == (9, 2, h, w, 3)
    assert suite.calibration_displacement.shape == (n, 2) and (suite.calibration_displacement > 0).all()
    assert suite.train_speed.shape == suite.train_displacement.shape == (12,)
    assert list(suite.frame_times) == TINY_SUITE_CLIPS["frame_times"]
    assert suite.metres_per_pixel == pytest.approx(1.28 / 64)
    assert truth.displacement.shape == (n, k) and truth.rest_frames.shape == (n, k, h, w, 3)
    assert truth.check_displacement.shape == (9,) and truth.half_extents.shape == (n, 3)
    # slides grow with the query speed
    assert (np.diff(truth.displacement, axis=1) > 0).all()
    # the objects are the split's first n, drawn as the clips rule draws them
    objects = sample_objects(ClipsConfig.from_dict(TINY_SUITE_CLIPS), "heldout_calib", SceneConfig())
    assert list(suite.object_ids) == list(objects["object_id"][:n])
    np.testing.assert_array_equal(truth.mass, objects["mass"][:n])
    np.testing.assert_array_equal(truth.friction, objects["friction"][:n])
    # every push starts from the same state: a query's context frame 0 is the calibration clips' frame 0
    assert (suite.context_frames[:, :, 0] == suite.calibration_frames[:, None, 0, 0]).all()
    assert (truth.rest_frames != suite.context_frames[:, :, 0]).any(axis=(2, 3, 4)).all()
    # the partner: Section 5's swap, no object its own
    np.testing.assert_array_equal(suite.partner, derangement(n, 11))
    assert sorted(suite.partner) == list(range(n)) and (suite.partner != np.arange(n)).all()
    assert suite_table_path(suite).read_bytes() == tiny_table_path.read_bytes()
    assert {*FILES} <= {p.name for p in tiny_suite.iterdir()}
    assert suite.checksum == suite.manifest["files"]["suite.npz"]


def test_frames_equal_the_clips_renderers(tiny_table_path, tmp_path):
    """Same objects, physics and renderer as `imply study clips render`: the same pixels and slides."""
    clips = ClipsConfig.from_dict({**TINY_SUITE_CLIPS, "n_heldout_calib": 2, "n_train_episodes": 3, "batch": 5})
    scene, speeds = SceneConfig(), ScoreConfig()
    cfg = SuiteConfig.from_dict({"n_objects": 2, "n_readout_train": 2, "n_readout_check": 1, "context_frames": 2})
    folder = build_suite(
        cfg,
        clips=clips,
        scene=scene,
        speeds=speeds,
        table_path=tiny_table_path,
        out_dir=tmp_path / "s",
        progress=False,
    )
    suite = load_suite(folder)
    truth = load_truth(suite)
    held, held_meta = render_split(clips, "heldout_calib", scene=scene, speeds=speeds, progress=False)
    train, train_meta = render_split(clips, "train", scene=scene, speeds=speeds, progress=False)
    held = held.reshape(2, 7, *held.shape[1:])
    np.testing.assert_array_equal(suite.calibration_frames, held[:, :2])
    np.testing.assert_array_equal(suite.context_frames, held[:, 2:, :2])
    np.testing.assert_array_equal(truth.rest_frames, held[:, 2:, -1])
    np.testing.assert_array_equal(truth.displacement, held_meta["displacement"].to_numpy().reshape(2, 7)[:, 2:])
    np.testing.assert_array_equal(suite.train_frames, train[:6][:, [0, -1]])
    np.testing.assert_array_equal(suite.check_frames, train[6:][:, [0, -1]])
    np.testing.assert_array_equal(suite.train_speed, train_meta["speed"][:6])
    np.testing.assert_array_equal(suite.train_displacement, train_meta["displacement"][:6])
    np.testing.assert_array_equal(truth.check_displacement, train_meta["displacement"][6:])


@pytest.fixture
def suite_copy(tiny_suite, tmp_path):
    folder = tmp_path / "suite"
    shutil.copytree(tiny_suite, folder)
    return folder


@pytest.mark.parametrize("name", ["suite.npz", "truth.npz", "table.npz"])
def test_a_flipped_byte_is_refused_naming_the_file(suite_copy, name):
    path = suite_copy / name
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0x01
    path.write_bytes(bytes(data))
    with pytest.raises(SuiteError, match=rf"{name}: checksum differs"):
        load_suite(suite_copy)


def test_truth_changed_after_loading_is_refused(suite_copy):
    suite = load_suite(suite_copy)
    shutil.copyfile(suite_copy / "suite.npz", suite_copy / "truth.npz")
    with pytest.raises(SuiteError, match=r"truth.npz: checksum differs"):
        load_truth(suite)


def test_missing_file_and_other_version_are_refused(suite_copy, tmp_path):
    manifest = json.loads((suite_copy / "manifest.json").read_text())
    (suite_copy / "manifest.json").write_text(json.dumps({**manifest, "version": SUITE_VERSION + 1}))
    with pytest.raises(SuiteError, match=rf"suite version {SUITE_VERSION + 1}; this imply reads version 1; rebuild"):
        load_suite(suite_copy)
    (suite_copy / "manifest.json").write_text(json.dumps(manifest))
    load_suite(suite_copy)
    (suite_copy / "table.npz").unlink()
    with pytest.raises(SuiteError, match=r"table.npz is missing"):
        load_suite(suite_copy)
    with pytest.raises(SuiteError, match=r"manifest.json is missing"):
        load_suite(tmp_path)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (
            {"n_objects": 7},
            r"suite.n_objects 7 is more than the 6 objects of split heldout_calib \(clips.n_heldout_calib",
        ),
        ({"n_readout_check": 5}, r"suite.n_readout_train \+ suite.n_readout_check \(4 \+ 5\) is more than the 8"),
        ({"context_frames": 4}, r"suite.context_frames 4 must be fewer than a clip's 4 frames"),
    ],
)
def test_settings_the_clips_cannot_give_are_refused(tiny_table_path, tmp_path, changes, message):
    with pytest.raises(SuiteError, match=message):
        build_tiny_suite(tmp_path / "s", tiny_table_path, **changes)
    assert not (tmp_path / "s").exists()


def test_split_outside_the_heldout_splits_is_refused():
    with pytest.raises(ValueError, match=r"suite.split: 'train' is not one of"):
        SuiteConfig.from_dict({"split": "train"})


def test_cli_build_gives_the_same_bytes_and_show_checks_it(tiny_suite, tiny_table_path, tmp_path, capsys):
    out = tmp_path / "cli"
    argv = [
        "suite",
        "build",
        "--suite-json",
        json.dumps(TINY_SUITE),
        "--clips-json",
        json.dumps(TINY_SUITE_CLIPS),
        "--table",
        str(tiny_table_path),
        "-o",
        str(out),
    ]
    assert main(argv) == 0
    for name in FILES:
        assert (out / name).read_bytes() == (tiny_suite / name).read_bytes(), name
    # a rebuild over a previous suite replaces it
    assert main(argv) == 0
    capsys.readouterr()
    assert main(["suite", "show", str(out)]) == 0
    shown = capsys.readouterr().out
    assert "6 of split heldout_calib" in shown and "16 x 64 px" in shown and "checksums  OK" in shown
    (out / "suite.npz").write_bytes(b"broken")
    assert main(["suite", "show", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "suite.npz: checksum differs" in err[0]


def test_cli_refuses_bad_settings_in_one_line_and_writes_nothing(tiny_table_path, tmp_path, capsys):
    out = tmp_path / "cli"
    argv = ["suite", "build", "--suite-json", '{"n_objects": 301}', "--table", str(tiny_table_path), "-o", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [
        "imply suite build: error: suite.n_objects 301 is more than the 300 objects of split heldout_calib "
        "(clips.n_heldout_calib)"
    ]
    assert not out.exists()
