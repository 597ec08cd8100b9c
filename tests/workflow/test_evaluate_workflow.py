"""The suite and the stand-ins through imply evaluate, run by Snakemake on a tiny config in a temp dir."""

from __future__ import annotations

import json

import pytest
import yaml

from workflow_helpers import ROOT, copy_workflow, planned, plant_table, snakemake

TINY = ROOT / "tests" / "config" / "evaluate_tiny.yaml"
TARGET = "results/paper/parts/evaluate.json"


@pytest.mark.slow
def test_the_evaluate_stage_builds_and_a_setting_reruns_only_what_reads_it(tmp_path, tiny_table_path, forked_imply):
    work = copy_workflow(tmp_path)
    plant_table(work, tiny_table_path)
    override = work / "tiny.yaml"
    override.write_text(TINY.read_text())
    snakemake(work, TARGET, "--configfile", str(override))

    manifest = json.loads((work / "results/suite/manifest.json").read_text())
    assert manifest["sizes"]["N"] == 6 and manifest["sizes"]["H"] == 32
    part = json.loads((work / TARGET).read_text())
    assert {"evBlindAurocAnch", "evOracleAnch", "evCollapseStatic"} <= set(part["numbers"])
    assert {c["id"] for c in part["claims"]} >= {"ev-blind-exposed-by-anchoring", "ev-collapse-flagged-static"}
    report = work / "results/evaluate/standins"
    assert (report / "report.md").read_text().startswith("# IMPLY evaluation")
    assert (work / "results/logs/suite_build.log").read_text().strip()
    assert (work / "results/logs/evaluate_standins.log").read_text().strip()

    assert planned(snakemake(work, "-n", TARGET, "--configfile", str(override))) == set()
    cfg = yaml.safe_load(override.read_text())
    cfg["evaluate"]["bootstrap"] = 60
    override.write_text(yaml.safe_dump(cfg))
    assert planned(snakemake(work, "-n", TARGET, "--configfile", str(override))) == {"evaluate_standins", "paper_part"}
