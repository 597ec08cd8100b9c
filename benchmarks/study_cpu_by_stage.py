"""Where a whole run of the study spent its CPU, stage by stage, and the wall time that CPU needs on two cores.

Reads a run's ``results/benchmarks/`` (Snakemake's ``benchmark:`` files, through
:func:`imply.paper.timings.read_benchmarks`) and sums each job's CPU seconds by stage: the rule file
of ``workflow/rules/`` that defines its rule, with the gap stage's file split by benchmark (the main
one, the other-contact one, the lab one). Beside each stage's CPU minutes it prints the running sum
over the stages kept in the order given, and that sum's floor on two cores (half of it): the least
wall time a default run holding those stages could take, before Snakemake's and each job's start
(``--overhead``: the whole process tree's CPU over the jobs', measured with ``/usr/bin/time``).

Usage: ``python benchmarks/study_cpu_by_stage.py results/benchmarks --overhead 1.19``
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

from imply.paper.timings import read_benchmarks

ROOT = Path(__file__).resolve().parents[1]
RULE = re.compile(r"^(?:local)?rule (\w+):", re.M)
GAP_PARTS = (("gap_lab_", "gap: lab benchmark"), ("gap_contact_", "gap: other-contact benchmark"))
# the order stages are kept in: what a default run would drop last comes first
ORDER = (
    "table",
    "clips",
    "section4",
    "model",
    "section5",
    "evaluate",
    "paper",
    "gap: main benchmark",
    "pixel",
    "gap: other-contact benchmark",
    "gap: lab benchmark",
)


def stage_of_rule(rules_dir: Path) -> dict[str, str]:
    """Each rule's stage: its rule file's name, the gap file's rules split by benchmark."""
    out = {}
    for path in sorted(rules_dir.glob("*.smk")):
        for name in RULE.findall(path.read_text()):
            stage = path.stem
            if stage == "gap":
                stage = next((label for prefix, label in GAP_PARTS if name.startswith(prefix)), "gap: main benchmark")
            out[name] = stage
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("benchmarks", type=Path, help="a run's results/benchmarks folder")
    ap.add_argument("--rules", type=Path, default=ROOT / "workflow" / "rules", help="the workflow's rule files")
    ap.add_argument("--overhead", type=float, default=1.0, help="process tree CPU over the jobs' CPU (default 1)")
    args = ap.parse_args(argv)
    jobs = read_benchmarks(args.benchmarks)
    if not jobs:
        print(f"no benchmark files under {args.benchmarks}", file=sys.stderr)
        return 2
    stages = stage_of_rule(args.rules)
    cpu: dict[str, float] = {}
    for job in jobs:
        stage = stages.get(job.rule, "other")
        cpu[stage] = cpu.get(stage, 0.0) + job.cpu_seconds / 60.0
    order = [s for s in ORDER if s in cpu] + sorted(s for s in cpu if s not in ORDER)
    print(f"{len(jobs)} jobs, {sum(cpu.values()):.1f} CPU-min; overhead factor {args.overhead:g}")
    print("| stage | CPU-min | kept so far, CPU-min | two-core floor of those, min |")
    print("|---|---|---|---|")
    total = 0.0
    for stage in order:
        total += cpu[stage]
        print(f"| {stage} | {cpu[stage]:.1f} | {total:.1f} | {total * args.overhead / 2:.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
