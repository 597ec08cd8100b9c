"""The gap stage's workflow on a tiny config: logs, sealed labels, diagnoses, benchmark part."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from workflow_helpers import copy_workflow


@pytest.mark.slow
def test_gap_workflow_tiny(tmp_path, repo_root):
    copy_workflow(tmp_path)
    target = "results/paper/parts/gap.json"
    cmd = [sys.executable, "-m", "snakemake", target, "--cores", "2", "--directory", str(tmp_path),
           "--configfile", str(repo_root / "tests/config/gap_tiny.yaml")]  # fmt: skip
    run = subprocess.run(cmd, cwd=tmp_path, capture_output=True, text=True)
    assert run.returncode == 0, run.stderr[-3000:]
    part = json.loads((tmp_path / target).read_text())
    assert part["stage"] == "gap"
    assert {"gapTopOneAcc", "gapFalseAlarm", "gapShrinkMedian", "gapNoneRecall"} <= set(part["numbers"])
    assert {c["id"] for c in part["claims"]} == {"gap-top1", "gap-null", "gap-shrink"}
    bench = json.loads((tmp_path / "results/gap/benchmark.json").read_text())["result"]
    assert bench["n_null"] == 2 and bench["n_outside"] == 1 and bench["n_library"] == 2
    # the diagnose rules never see the labels: the push logs hold no label column
    log = (tmp_path / "results/gap/logs/tilt_x-0.csv").read_text().splitlines()[0]
    assert log.split(",") == ["object_id", "speed", "direction", "displacement", "size_x", "size_y", "size_z", "mass"]
    assert (tmp_path / "results/gap/benchmark.md").read_text().startswith("# Gap diagnostic benchmark")
