"""The documentation's snapshot of a study run: complete, stamped, and made by code that reports what HEAD reports."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from imply.paper.registry import load_registry
from imply.paper.snapshot import FILES, figure_paths, fill_readme, label, read_stamp, readme_line

ROOT = Path(__file__).resolve().parents[2]
SNAPSHOT = ROOT / "docs" / "snapshot"
REFRESH = "refresh it: run the study, then `snakemake --cores 2 snapshot`, and commit docs/snapshot and README.md"


@pytest.fixture(scope="module")
def stamp():
    found = read_stamp(SNAPSHOT)
    if found is None:
        # the docs then say that no snapshot is committed (imply.docs_pages.ph_snapshot); nothing can be stale
        pytest.skip(f"no snapshot is committed in docs/snapshot; to make one: {REFRESH}")
    return found


def test_the_snapshot_reports_the_numbers_head_s_study_code_reports(stamp):
    """A snapshot made by study code whose numbers.json had other keys than HEAD's registry is stale."""
    # the paper's numbers this study does not run (no stage) are in the registry but never in numbers.json
    registered = sorted(name for name, e in load_registry().entries.items() if e.stage)
    held = sorted(json.loads((SNAPSHOT / "results/paper/numbers.json").read_text()))
    assert held == sorted(stamp["numbers"])
    assert held == registered, f"the snapshot's numbers differ from the registry's at HEAD; {REFRESH}"


def test_the_snapshot_holds_every_file_the_docs_show(stamp):
    for rel in [*FILES, *figure_paths(ROOT / "docs")]:
        assert (SNAPSHOT / rel).is_file(), f"{rel} is not in the snapshot; {REFRESH}"


def test_the_stamp_names_its_run(stamp):
    assert len(stamp["commit"]) == 40 and stamp["machine"]["cpu"] and stamp["machine"]["instruction_set"]
    assert stamp["wall_seconds"] > 0
    # the paper's claims and this project's targets, each counted over its own denominator
    c = stamp["claims"]
    for tally in [c["paper"], c["project"]] if "paper" in c else [c]:
        assert 0 < tally["hold"] <= tally["checked"]
    assert stamp["commit"][:7] in label(stamp)


def test_the_readme_line_is_the_snapshot_s(stamp):
    readme = (ROOT / "README.md").read_text()
    assert readme_line(stamp) in readme, "README.md's snapshot line is not the snapshot's; " + REFRESH
    assert fill_readme(readme, stamp) == readme
