"""The pixel-space world model beyond the paper, run by Snakemake on a tiny config in a temp dir: both variants
trained, evaluated through imply evaluate with several sample sets, scored into the part, Figure 3 and the
reproduction report's own section; a setting reruns only what reads it."""

from __future__ import annotations

import json

import pytest
import yaml

from imply.paper.registry import load_registry
from workflow_helpers import ROOT, copy_workflow, planned, plant_table, snakemake

TINY = ROOT / "tests" / "config" / "pixel_tiny.yaml"
TARGETS = ["results/paper/reproduction.md", "results/paper/figures/figure3.png"]


@pytest.mark.slow
def test_the_pixel_stage_builds_and_a_setting_reruns_only_what_reads_it(tmp_path, tiny_table_path, forked_imply):
    work = copy_workflow(tmp_path)
    plant_table(work, tiny_table_path)
    override = work / "tiny.yaml"
    override.write_text(TINY.read_text())
    snakemake(work, *TARGETS, "--configfile", str(override))

    part = json.loads((work / "results/paper/parts/pixel.json").read_text())
    registered = {e.name for e in load_registry().of_stage("pixel")}
    assert set(part["numbers"]) == registered
    assert part["numbers"]["pxNSamples"] == 3 and part["numbers"]["pxNObjects"] == 6
    assert {c["id"] for c in part["claims"]} == {
        "px-moves-with-the-action",
        "px-frames-readable",
        "px-calibrated-tracks-its-object",
        "px-uncertain-without-calibration",
        "px-anchored-chooses-among-samples",
    }
    report = (work / "results/paper/reproduction.md").read_text()
    assert "## Beyond the paper: a pixel-space, stochastic world model" in report
    assert "| pxSelAnchTrack |" in report.split("## Beyond the paper")[1]
    calib = json.loads((work / "results/pixel/evaluate/calib/results.json").read_text())["models"][0]
    assert calib["kind"] == "frames" and calib["n_samples"] == 3
    assert calib["readout"]["name"] == "frame difference"  # fitted on real clips, never on generated ones
    assert (work / "results/paper/figures/figure3.pdf").stat().st_size > 0
    for log in ("pixel_train_calib", "pixel_evaluate_nocalib", "pixel_score", "paper_figure3"):
        assert (work / f"results/logs/{log}.log").is_file()

    assert planned(snakemake(work, "-n", *TARGETS, "--configfile", str(override))) == set()
    cfg = yaml.safe_load(override.read_text())
    cfg["evaluate"]["samples"] = 4
    override.write_text(yaml.safe_dump(cfg))
    rerun = planned(snakemake(work, "-n", *TARGETS, "--configfile", str(override)))
    assert "pixel_train" not in rerun and "pixel_evaluate" in rerun
    cfg["pixel"]["recipe"]["epochs"] = 3
    override.write_text(yaml.safe_dump(cfg))
    assert "pixel_train" in planned(snakemake(work, "-n", *TARGETS, "--configfile", str(override)))
