"""The snapshot times the default run and the gap_development target apart, and counts the two kinds of claims
apart."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

from imply.paper.snapshot import claims_sentence, development_times, stage_times

ROOT = Path(__file__).resolve().parents[2]


def _job(root: Path, rule: str, wildcards: str, seconds: float, end: float) -> None:
    path = root / "results" / "benchmarks" / rule / f"{wildcards}.tsv"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"s\tcpu_time\tmax_rss\n{seconds}\t{seconds / 2}\t100\n")
    os.utime(path, (end, end))


def test_development_jobs_are_timed_apart_from_the_default_run(tmp_path):
    shutil.copytree(ROOT / "workflow" / "rules", tmp_path / "workflow" / "rules")
    _job(tmp_path, "table", "all", 100.0, 1_000_100.0)
    _job(tmp_path, "gap_benchmark", "all", 50.0, 1_000_300.0)
    _job(tmp_path, "gap_lab_generate", "sealed", 60.0, 1_000_200.0)
    # after the default run: the development rules, and the lab rules' development set
    _job(tmp_path, "gap_dev_generate", "all", 400.0, 1_001_000.0)
    _job(tmp_path, "gap_lab_generate", "development", 300.0, 1_001_200.0)
    times = stage_times(tmp_path)
    assert times["jobs"] == 3 and times["wall_seconds"] == 300.0
    assert "development" not in {row["stage"] for row in times["stages"]}
    dev = development_times(tmp_path)
    assert dev == {"jobs": 2, "wall_seconds": 600.0, "cpu_seconds": 350.0}


def test_claims_sentence_counts_the_paper_apart():
    new = {"claims": {"paper": {"checked": 36, "hold": 30}, "project": {"checked": 39, "hold": 30}}}
    assert claims_sentence(new).startswith("30 of the paper's 36 claims hold; 30 of this project's 39 own targets")
    assert claims_sentence({"claims": {"checked": 75, "hold": 60}}) == "60 of its 75 claims hold"
