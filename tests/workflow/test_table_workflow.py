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
def test_table_targets_build_and_only_dependants_rerun(tmp_path, forked_imply):
    work = copy_workflow(tmp_path)
    override = work / "small.yaml"
    # the tiny configs' table (tests/config/core_small.yaml) on a coarser grid: the rule, not the table, is tested
    small = yaml.safe_load((ROOT / "tests/config/core_small.yaml").read_text())
    for axis in ("speeds", "masses", "frictions"):
        small["table"][axis]["n"] = 4
    small["table_check"]["cells"] = 2
    override.write_text(yaml.safe_dump(small))
    targets = ["results/table/table.npz", "results/table/scene.xml"]
    snakemake(work, *targets, "--configfile", str(override))
    table = PushTable.load(work / "results/table/table.npz")
    assert table.log_d.shape == (4, 4, 4) and table.meta["numerical_error"]["cells"] == 2
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


def test_whole_dag_plans(tmp_path, forked_imply):
    work = copy_workflow(tmp_path)
    proc = snakemake(work, "-n")
    assert "table" in planned_rules(proc)


def test_bad_config_is_refused_naming_the_option(tmp_path, forked_imply):
    work = copy_workflow(tmp_path)
    bad = work / "bad.yaml"
    bad.write_text("score:\n  grid: 3\n")
    proc = snakemake(work, "--configfile", str(bad), "-n", check=False)
    assert proc.returncode != 0
    assert "grid" in (proc.stdout + proc.stderr)


def test_same_config_same_table_bytes(tmp_path):
    """The table file's bytes do not depend on the threads that built it (a 4 x 4 x 4 grid: 64 cells on two threads)."""
    from imply.sim import SceneConfig
    from imply.table import TableGrid, build_table

    grid = TableGrid(0.15, 1.05, 4, 0.2, 2.0, 4, 0.1, 0.6, 4)
    a = tmp_path / "a.npz"
    b = tmp_path / "b.npz"
    build_table(SceneConfig(), grid, nthread=2).save(a)
    build_table(SceneConfig(), grid, nthread=1).save(b)
    assert a.read_bytes() == b.read_bytes()
    assert np.load(a)["log_d"].shape == (4, 4, 4)


def test_the_planted_tiny_table_is_the_tiny_configs_table(tiny_table):
    """Every tiny workflow config that plants the tests' tiny table (instead of running the table rule) asks for that
    table: the same grid, scene and check as tests/config/core_small.yaml, which built it."""
    from conftest import TINY_GRID, tiny_workflow_config

    want = tiny_workflow_config()
    assert tiny_table.meta["grid"] == TINY_GRID.__dict__ and tiny_table.meta["numerical_error"]["cells"] == 4
    for name in ("gap_tiny", "evaluate_tiny", "pixel_tiny", "section4_small", "core_small"):
        cfg = tiny_workflow_config(ROOT / f"tests/config/{name}.yaml")
        for key in ("scene", "table", "table_check"):
            assert cfg[key] == want[key], (name, key)
