"""The Section 5 rules end to end on planted synthetic features, a real (random) encoder and tiny suites.

Training reads synthetic features (no rendering); the held-out rollouts go through
``imply evaluate`` on suites rendered small, with the encoder the features would come from.
"""

from __future__ import annotations

import json
import os
import shutil
import time

import pytest

from suite_helpers import build_eight_frame_suite, write_tiny_encoder
from synthetic_features import synth_split
from workflow_helpers import copy_workflow, plant_table, snakemake

pytestmark = pytest.mark.slow

SPLITS = (("train", 40, False), ("heldout_calib", 8, True), ("heldout_nocalib", 10, True), ("validation", 8, True))


def test_section5_rules_run(repo_root, tiny_table_path, tmp_path, forked_imply):
    work = copy_workflow(tmp_path / "wf")
    shutil.copy(repo_root / "tests/config/model_small.yaml", work / "small.yaml")
    # the upstream outputs this stage reads, planted oldest first so nothing upstream reruns
    plant_table(work, tiny_table_path)
    clips, feats = work / "results/clips", work / "results/features"
    clips.mkdir()
    feats.mkdir()
    (work / "results/encoder").mkdir()
    for split, n, held in SPLITS:  # the tiny encoder's grid and width
        npz, csv = synth_split(feats, split, n, held, seed=len(split), grid=(1, 4), dim=24)
        shutil.move(csv, clips / f"{split}.csv")
        (clips / f"{split}.npz").write_bytes(b"planted")
    (clips / "pretrain.npz").write_bytes(b"planted")
    (clips / "pretrain.csv").write_text("planted\n")
    write_tiny_encoder(work / "results/encoder/encoder.pt")
    suites = [
        build_eight_frame_suite(work / "results/suite", tiny_table_path),
        build_eight_frame_suite(work / "results/section5/suite_nocalib", tiny_table_path, n_objects=5),
    ]
    now = time.time()
    order = [
        work / "results/table/table.npz",
        *clips.iterdir(),
        work / "results/encoder/encoder.pt",
        *feats.iterdir(),
        *(f for s in suites for f in sorted(s.iterdir())),
    ]
    for i, path in enumerate(order):
        os.utime(path, (now - 1000 + i, now - 1000 + i))
    target = [
        "results/paper/parts/section5.json",
        "results/paper/tables/table3.tex",
        "results/paper/figures/figure2.png",
        "results/model/training.png",
    ]
    configs = (str(work / "config.yaml"), str(work / "small.yaml"))
    run = snakemake(
        work, "--configfile", *configs, "--rerun-triggers", "mtime", "--", *target, check=False, timeout=600
    )
    assert run.returncode == 0, run.stderr[-3000:]
    for upstream in ("clips_render", "encoder_encode", "suite_build", "section5_suite_nocalib"):
        assert upstream not in run.stderr
    part = json.loads((work / target[0]).read_text())
    assert part["numbers"]["vjNTwo"] == 6 and part["numbers"]["vjNOne"] == 5  # the suites' objects
    assert "vjCTrack" in part["numbers"] and "vjSOneCTrack" not in part["numbers"]  # one seed configured
    history = json.loads((work / "results/model/calib/seed0/training.json").read_text())["history"]
    assert [h["epoch"] for h in history] == [1, 2] and {"own_track", "swap_track", "own_lt_swap_self"} <= set(
        history[0]
    )
    # the context-free model trains its own epochs (model.train.context_free_epochs)
    nocalib = json.loads((work / "results/model/nocalib/seed0/training.json").read_text())["history"]
    assert [h["epoch"] for h in nocalib] == [1]
    assert "vjBErr" in part["numbers"] and "vjBQErr" in part["numbers"]
    report = json.loads((work / "results/section5/evaluate/calib_seed0/results.json").read_text())
    assert report["models"][0]["kind"] == "latents" and report["models"][0]["readout"]["name"] == "ridge on encode()"
    metrics = json.loads((work / "results/section5/metrics.json").read_text())["result"]
    assert metrics["seeds"][0]["readouts"]["calib"]["fitted_on"].endswith("real training clips")
    for f in (
        "model/calib/seed0/checkpoint.pt",
        "model/training.png",
        "section5/evaluate/nocalib_seed0/report.md",
        "paper/tables/table3.tex",
        "paper/figures/figure2.png",
        "logs/model_train_calib_seed0.log",
        "section5/metrics.json",
    ):
        assert (work / "results" / f).exists(), f
