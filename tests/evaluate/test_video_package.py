"""The suite as files (``imply suite export``) and generated videos read back (``imply evaluate --videos``): the
package holds no truth, lossless frames score exactly as in process, and a bad folder is refused before scoring."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from imply.cli import main
from imply.evaluate.config import EvaluateConfig
from imply.evaluate.harness import evaluate
from imply.evaluate.standins import blind, oracle
from imply.evaluate.suite import load_suite, load_truth
from imply.evaluate.video_package import (
    VideoFolderError,
    case_list,
    check_videos,
    export_package,
    read_mp4,
    read_videos,
    write_mp4,
)
from video_helpers import CONDITIONS, generate_videos

FAST = EvaluateConfig(bootstrap=50)


def test_the_package_has_every_case_and_no_truth(tiny_suite, tmp_path):
    suite = load_suite(tiny_suite)
    m = export_package(suite, tmp_path / "pkg", conditions=CONDITIONS)
    cases = pd.read_csv(tmp_path / "pkg" / "cases.csv")
    assert len(cases) == m["n_cases"] == suite.n_objects * 3 * suite.n_speeds
    assert set(cases["output"]) == {f"{c}.mp4" for c in cases["case_id"]}
    none = cases[cases["condition"] == "none"]
    assert none["calibration_slide_1"].isna().all() and none["calibration_video_1"].isna().all()
    other = cases[cases["condition"] == "other"].iloc[0]
    n = list(suite.object_ids).index(other["object_id"])
    assert other["calibration_object_id"] == suite.object_ids[suite.partner[n]]
    assert np.isclose(other["calibration_slide_1"], suite.calibration_displacement[suite.partner[n], 0])
    first = cases.iloc[0]
    assert (tmp_path / "pkg" / first["calibration_video_1"]).is_file()
    assert len(list((tmp_path / "pkg" / first["context"]).glob("*.png"))) == suite.context_frames.shape[2]
    frames, fps = read_mp4(tmp_path / "pkg" / first["calibration_video_1"])
    assert frames.shape == suite.calibration_frames.shape[2:] and fps == 30.0
    # no truth value anywhere in the package: the query slides, masses and frictions
    truth = load_truth(suite)
    text = "".join(p.read_text() for p in (tmp_path / "pkg").glob("*.*") if p.suffix in (".csv", ".json", ".md"))
    for value in np.concatenate([truth.displacement.ravel(), truth.mass, truth.friction]):
        assert repr(float(value)) not in text and f"{value:.6f}" not in text
    assert not list((tmp_path / "pkg").rglob("truth*"))
    with pytest.raises(ValueError, match="must be a new or empty folder"):
        export_package(suite, tmp_path / "pkg", conditions=CONDITIONS)


def test_lossless_frames_score_exactly_as_in_process(tiny_suite, tmp_path):
    suite = load_suite(tiny_suite)
    model = oracle(suite)
    (direct,) = evaluate([model], suite=suite, settings=FAST)
    folder = tmp_path / model.name
    generate_videos(suite, model, folder)
    (from_files,) = evaluate(suite=suite, rollouts=[read_videos(folder, suite, CONDITIONS)], settings=FAST)
    assert from_files.model == "oracle"
    assert json.dumps(from_files.to_dict(), sort_keys=True) == json.dumps(direct.to_dict(), sort_keys=True)


def test_videos_at_another_size_and_through_h264_read_back_close(tiny_suite, tmp_path):
    suite = load_suite(tiny_suite)
    model = blind(suite)
    (direct,) = evaluate([model], suite=suite, settings=FAST)
    d0 = direct.readings.displacement
    # H.264 at 4x the camera (64 x 256), read back by an area average: the codec moves pixels, the slides little
    generate_videos(suite, model, tmp_path / "blind", mp4=True, scale=4)
    (read,) = evaluate(suite=suite, rollouts=[read_videos(tmp_path / "blind", suite, CONDITIONS)], settings=FAST)
    assert np.median(np.abs(np.log(read.readings.displacement / d0))) < 0.1
    # at the tiny camera's own 16 x 64, chroma subsampling smears the box: what the codec check is for
    generate_videos(suite, model, tmp_path / "tiny", mp4=True)
    (tiny,) = evaluate(suite=suite, rollouts=[read_videos(tmp_path / "tiny", suite, CONDITIONS)], settings=FAST)
    assert np.median(np.abs(np.log(tiny.readings.displacement / d0))) > np.median(
        np.abs(np.log(read.readings.displacement / d0))
    )
    # the readout is checked on the real check clips through each submission's own encoding, and the report says so
    assert direct.readout.encoding is None and np.isnan(direct.readout.r2_codec)
    assert read.readout.encoding.startswith("h264, 256x64 px, 10 fps") and np.isfinite(read.readout.r2_codec)
    assert tiny.readout.encoding.startswith("h264, 64x16 px") and tiny.readout.error_codec > read.readout.error_codec


def test_a_bad_folder_is_refused_with_one_line_per_problem_and_nothing_scored(tiny_suite, tmp_path, capsys):
    suite = load_suite(tiny_suite)
    model = oracle(suite)
    cases = case_list(suite, CONDITIONS)
    folder = tmp_path / "bad"
    generate_videos(suite, model, folder, mp4=True, skip=(cases[0].case_id,))
    (folder / f"{cases[1].case_id}.mp4").write_bytes(b"not a video")
    write_mp4(folder / f"{cases[2].case_id}.mp4", suite.context_frames[0, 0, :1].repeat(4, 0), 25.0)  # another fps
    (folder / "notes.txt").write_text("mine")
    with pytest.raises(VideoFolderError) as err:
        check_videos(folder, suite, CONDITIONS)
    lines = err.value.problems
    kinds = [line.split(": ")[1] for line in lines]
    assert kinds == [
        "extra files (not a video or a folder of PNG frames)",
        "missing",
        "undecodable",
        "mixed frame rates",
    ]
    assert f"missing: 1 ({cases[0].case_id}.mp4)" in lines[1]
    assert "25 fps: 1 videos" in lines[3] and "10 fps:" in lines[3]
    report = tmp_path / "report"
    args = ["evaluate", "--videos", str(folder), "--suite", str(tiny_suite), "-o", str(report), "--no-progress"]
    assert main([*args, "--check"]) == 2
    err_text = capsys.readouterr().err
    assert err_text.count("error: ") == 4 and "undecodable: 1" in err_text and "(nothing scored)" in err_text
    assert main(args) == 2 and not report.exists()
    # a clip of the context frames alone has nothing after them
    short = tmp_path / "short"
    generate_videos(suite, model, short, mp4=True)
    C = suite.context_frames.shape[2]
    write_mp4(short / f"{cases[3].case_id}.mp4", suite.context_frames[0, 0, :C], 10.0)
    with pytest.raises(VideoFolderError, match=rf"no frame after the {C} context frames: 1"):
        check_videos(short, suite, CONDITIONS)


def test_export_and_evaluate_from_the_command_line(tiny_suite, tmp_path):
    pkg = tmp_path / "pkg"
    assert main(["suite", "export", str(tiny_suite), "-o", str(pkg), "--size", "32x128", "--fps", "12"]) == 0
    m = json.loads((pkg / "manifest.json").read_text())
    assert m["size"] == {"height": 32, "width": 128} and m["fps"] == 12.0 and m["camera"]["height"] == 16
    assert main(["suite", "export", str(tiny_suite), "-o", str(tmp_path / "odd"), "--size", "33x128"]) == 2
    suite = load_suite(tiny_suite)
    folder = tmp_path / "oracle"
    generate_videos(suite, oracle(suite), folder)
    assert main(["evaluate", "--videos", str(folder), "--suite", str(tiny_suite), "--check"]) == 0
    out = tmp_path / "report"
    assert (
        main(
            [
                "evaluate",
                "--videos",
                str(folder),
                "--suite",
                str(tiny_suite),
                "-o",
                str(out),
                "--no-progress",
                "--bootstrap",
                "20",
            ]
        )
        == 0
    )
    results = json.loads((out / "results.json").read_text())
    assert results["models"][0]["model"] == "oracle" and results["models"][0]["kind"] == "frames"


def test_the_file_door_example_runs_as_written(tiny_suite, tmp_path, repo_root, forked_imply):
    """The file-door how-to's three commands, as written, in a folder whose results/suite is the tiny suite (each
    ``imply`` in a fork of the worker's fork server)."""
    import re
    import shlex
    import subprocess
    import sys

    text = (repo_root / "docs" / "how-to" / "rollouts-elsewhere.md").read_text()
    block = re.search(r"```bash\n(imply suite export .*?)```", text, re.S)
    assert block, "the file-door how-to must hold its example as a ```bash block starting 'imply suite export'"
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "suite").symlink_to(tiny_suite)
    (tmp_path / "examples").symlink_to(repo_root / "examples")
    for line in block.group(1).strip().splitlines():
        argv = shlex.split(line)
        if argv[0] == "python":
            argv = [sys.executable, *argv[1:]]
        run = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True)
        assert run.returncode == 0, (line, run.stderr[-2000:])
    results = json.loads((tmp_path / "my-video-report" / "results.json").read_text())
    (model,) = results["models"]
    assert model["model"] == "my-videos" and model["kind"] == "frames"


def test_a_command_in_its_own_environment_generates_then_is_scored_and_resumes(tiny_suite, tmp_path, repo_root, capsys):
    import sys

    script = repo_root / "examples" / "video_world_model.py"
    out = tmp_path / "report"
    command = f"{sys.executable} {script} {{package}} {{out}} --cases {{cases}}"
    args = [
        "evaluate",
        "--command",
        command,
        "--name",
        "power-law",
        "--suite",
        str(tiny_suite),
        "-o",
        str(out),
        "--no-progress",
        "--bootstrap",
        "20",
    ]
    assert main(args) == 0
    results = json.loads((out / "results.json").read_text())
    assert results["models"][0]["model"] == "power-law"
    videos = tmp_path / "report.videos" / "power-law"
    n = len(list(videos.glob("*.mp4")))
    assert n == load_suite(tiny_suite).n_objects * 3 * 5
    # interrupted: two videos lost; a rerun asks the command for those two only
    lost = sorted(videos.glob("*.mp4"))[:2]
    for p in lost:
        p.unlink()
    assert main([*args, "--force"]) == 0
    runs = [line for line in (tmp_path / "report.command.log").read_text().splitlines() if line.startswith("$ ")]
    assert [r.rsplit("# ", 1)[1] for r in runs] == [f"{n} cases", "2 cases"]
    assert all(p.exists() for p in lost)
    # a command that fails stops with its last lines, nothing scored
    bad = [
        "evaluate",
        "--command",
        f"{sys.executable} -c \"import sys; print('no GPU here'); sys.exit(3)\"",
        "--suite",
        str(tiny_suite),
        "-o",
        str(tmp_path / "bad"),
        "--no-progress",
    ]
    assert main(bad) == 2
    err = capsys.readouterr().err
    assert "--command exited with status 3" in err and "no GPU here" in err
    assert not (tmp_path / "bad").exists()


def test_slides_no_pushed_box_could_make_are_flagged(tiny_suite, tmp_path, capsys):
    import sys

    sys.path.insert(0, str(tmp_path))
    (tmp_path / "millimetres.py").write_text(
        "import numpy as np\n"
        "class M:\n    kind = 'displacements'\n    name = 'millimetres'\n"
        "    def rollout(self, request):\n"
        "        return np.tile(1000.0 * 0.2 * (request.query_speeds / 0.55) ** 2, (len(request.object_ids), 1))\n"
        "def build(suite):\n    return M()\n"
    )
    out = tmp_path / "report"
    assert (
        main(
            [
                "evaluate",
                "--model",
                str(tmp_path / "millimetres.py") + ":build",
                "--suite",
                str(tiny_suite),
                "-o",
                str(out),
                "--no-progress",
                "--bootstrap",
                "20",
            ]
        )
        == 0
    )
    err = capsys.readouterr().err
    assert "millimetres: 90 rollout(s) read a slide more than ten times" in err
    assert "read a slide more than ten times the longest real one" in (out / "report.md").read_text()
