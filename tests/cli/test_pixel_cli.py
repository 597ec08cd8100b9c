"""``imply study pixel train`` on a tiny clip split: it writes a checkpoint and a history, and refuses bad input in one
line, naming the option, without writing anything."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from imply.cli import main
from imply.models.pixel_video import load_pixel_video

pytestmark = pytest.mark.usefixtures("one_torch_thread")


@pytest.fixture(scope="module")
def clips(tmp_path_factory):
    """4 objects x (2 calibration + 1 query) clips of 4 frames, 12 x 48 px: a red box sliding right."""
    d = tmp_path_factory.mktemp("pixel_clips")
    frames, rows = [], []
    for i in range(4):
        for role, v in (("calibration_0", 0.3), ("calibration_1", 0.8), ("query", 0.5)):
            clip = np.full((4, 12, 48, 3), 90, np.uint8)
            for t in range(4):
                c = 3 + int(round(20 * v * (1 + i / 4) * t / 3))
                clip[t, 4:8, c : c + 4] = (200, 40, 40)
            frames.append(clip)
            rows.append({"clip_id": len(rows), "object_id": f"o{i}", "role": role, "speed": v})
    np.savez(d / "train.npz", frames=np.stack(frames), clip_id=np.arange(len(rows)))
    pd.DataFrame(rows).to_csv(d / "train.csv", index=False)
    return d / "train.npz"


RECIPE = {"width": 8, "latent": 2, "frames": [3], "epochs": 2, "batch_size": 2}


def test_train_writes_the_checkpoint_and_history(clips, tmp_path):
    out, history = tmp_path / "m.pt", tmp_path / "h.json"
    assert (
        main(
            [
                "study",
                "pixel",
                "train",
                "--clips",
                str(clips),
                "--recipe-json",
                json.dumps(RECIPE),
                "--variant",
                "calib",
                "--threads",
                "1",
                "-o",
                str(out),
                "--history",
                str(history),
                "--no-progress",
            ]
        )
        == 0
    )
    model, epochs = load_pixel_video(out)
    assert model.calibrated and len(epochs) == 2
    doc = json.loads(history.read_text())
    assert doc["variant"] == "calib" and doc["recipe"]["frames"] == [3] and doc["epochs"][0]["seconds"] > 0


@pytest.mark.parametrize(
    ("recipe", "message"),
    [
        ({**RECIPE, "depth": 3}, "unknown --recipe-json option(s): depth"),
        ({**RECIPE, "frames": [5]}, "--recipe-json frames: index 5 is past the clips' 4 frames"),
        ({**RECIPE, "keypoint_sd": 0}, "keypoint_sd"),
    ],
)
def test_train_refuses_a_bad_recipe_naming_it_and_writes_nothing(clips, tmp_path, capsys, recipe, message):
    out = tmp_path / "m.pt"
    assert (
        main(
            [
                "study",
                "pixel",
                "train",
                "--clips",
                str(clips),
                "--recipe-json",
                json.dumps(recipe),
                "--variant",
                "nocalib",
                "--threads",
                "1",
                "-o",
                str(out),
                "--no-progress",
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert err.startswith("imply study pixel train: error:") and message in err and err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_score_refuses_a_folder_that_is_not_a_report(tmp_path, capsys):
    (tmp_path / "h.json").write_text(json.dumps({"epochs": []}))
    assert (
        main(
            [
                "study",
                "pixel",
                "score",
                "--calib",
                str(tmp_path),
                "--nocalib",
                str(tmp_path),
                "--calib-history",
                str(tmp_path / "h.json"),
                "--nocalib-history",
                str(tmp_path / "h.json"),
                "-o",
                str(tmp_path / "m.json"),
            ]
        )
        == 2
    )
    assert "is not an imply evaluate report" in capsys.readouterr().err
    assert not (tmp_path / "m.json").exists()
