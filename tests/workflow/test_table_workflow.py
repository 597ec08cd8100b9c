"""The table rules of the workflow, on a tiny grid in a temporary copy of the workflow."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from imply.table import PushTable
from workflow_helpers import ROOT, copy_workflow, snakemake


def planned_rules(proc) -> set[str]:
    rules, in_stats = set(), False
    for line in proc.stdout.splitlines():
        if line.startswith("job "):
            in_stats = True
            continue
        if in_stats:
            parts = line.split()
            if not parts or parts[0] == "total":
                break
            if len(parts) == 2 and parts[1].isdigit():
                rules.add(parts[0])
    return rules


@pytest.mark.slow
def test_table_targets_build_and_only_dependants_rerun(tmp_path):
    work = copy_workflow(tmp_path)
    override = work / "small.yaml"
    override.write_text((ROOT / "tests/config/core_small.yaml").read_text())
    targets = ["results/table/table.npz", "results/table/scene.xml"]
    snakemake(work, *targets, "--configfile", str(override))
    table = PushTable.load(work / "results/table/table.npz")
    assert table.log_d.shape == (7, 6, 6)
    assert (work / "results/logs/table.log").read_text().strip()
    assert "<mujoco" in (work / "results/table/scene.xml").read_text()

    # nothing to do when nothing changed
    again = snakemake(work, "-n", *targets, "--configfile", str(override))
    assert planned_rules(again) == set()

    # a table-axis change reruns the table, not the scene export
    cfg = yaml.safe_load(override.read_text())
    cfg["table"]["speeds"]["n"] = 8
    override.write_text(yaml.safe_dump(cfg))
    changed = snakemake(work, "-n", *targets, "--configfile", str(override))
    assert planned_rules(changed) == {"table"}


def test_whole_dag_plans(tmp_path):
    work = copy_workflow(tmp_path)
    proc = snakemake(work, "-n")
    assert "table" in planned_rules(proc)


def test_bad_config_is_refused_naming_the_option(tmp_path):
    work = copy_workflow(tmp_path)
    bad = work / "bad.yaml"
    bad.write_text("score:\n  grid: 3\n")
    proc = snakemake(work, "--configfile", str(bad), "-n", check=False)
    assert proc.returncode != 0
    assert "grid" in (proc.stdout + proc.stderr)


def test_same_config_same_table_bytes(tmp_path):
    from conftest import TINY_GRID
    from imply.sim import SceneConfig
    from imply.table import build_table

    a = tmp_path / "a.npz"
    b = tmp_path / "b.npz"
    build_table(SceneConfig(), TINY_GRID, nthread=2).save(a)
    build_table(SceneConfig(), TINY_GRID, nthread=1).save(b)
    assert a.read_bytes() == b.read_bytes()
    assert np.load(a)["log_d"].shape == (7, 6, 6)
