"""The study's own Snakemake report: every figure and table is marked for it, every caption exists."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
RULES = sorted((ROOT / "workflow" / "rules").glob("*.smk"))
# report(PATH, caption=CAPTION, category=CATEGORY, ...): the marked output, its caption and its group
MARKED = re.compile(
    r'report\(\s*"(?P<path>[^"]+)",\s*caption="(?P<caption>[^"]+)",\s*category="(?P<category>[^"]+)"', re.S
)


def marked_outputs() -> dict[str, tuple[Path, str]]:
    """Marked output path -> (its caption file, its category), from every rules file."""
    out = {}
    for rules in RULES:
        for m in MARKED.finditer(rules.read_text()):
            out[m["path"]] = ((rules.parent / m["caption"]).resolve(), m["category"])
    return out


def test_every_caption_and_the_workflow_description_exist():
    marked = marked_outputs()
    assert len(marked) >= 10
    missing = sorted(f"{path}: {caption}" for path, (caption, _) in marked.items() if not caption.is_file())
    assert missing == []
    described = re.search(r'^report:\s*"([^"]+)"', (ROOT / "Snakefile").read_text(), re.M)
    assert described and (ROOT / described[1]).is_file()


def test_every_figure_and_table_of_the_study_is_in_the_report_grouped_by_stage():
    marked = marked_outputs()
    stage_of = {path: category for path, (_, category) in marked.items()}
    assert stage_of["results/paper/figures/figure1.png"] == stage_of["results/paper/tables/table1.tex"]
    assert stage_of["results/paper/tables/table2.tex"] == stage_of["results/section4/metrics.json"]
    assert stage_of["results/paper/figures/figure2.png"] == stage_of["results/paper/tables/table3.tex"]
    assert stage_of["results/model/training.png"] == stage_of["results/section5/metrics.json"]
    assert "results/paper/reproduction.md" in marked and "results/gap/benchmark.md" in marked
    # every picture any rule writes is in the report
    pictures = {p for rules in RULES for p in re.findall(r'"(results/[^"]+\.png)"', rules.read_text())}
    assert pictures and pictures <= set(marked)
