"""Time the Section 4 DAG (after the table) on the default config.

Copies Snakefile, workflow/ and config.yaml into a scratch directory, puts an existing
table there (default: results/table/table.npz; build it first with
``snakemake --cores 2 results/table/table.npz``), and times
``snakemake --cores N`` on the Section 4 targets and the paper merge (restricted to
the section4 part, so no other stage is built). Prints one JSON line with the wall
time and per-rule times from the rules' log timestamps. Target: under 5 minutes on 2
cores.

    nice -n 10 python benchmarks/bench_section4.py --cores 2
"""

from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TARGETS = [
    "results/paper/tables/table1.tex",
    "results/paper/tables/table2.tex",
    "results/paper/figures/figure1.pdf",
    "results/paper/figures/figure1.png",
    "results/paper/macros.tex",
    "results/paper/numbers.json",
    "results/paper/reproduction.md",
    "results/paper/reproduction.csv",
]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cores", type=int, default=2)
    ap.add_argument("--table", default=str(ROOT / "results/table/table.npz"), help="existing push table")
    ap.add_argument("--workdir", help="scratch directory (default: a new temporary one, removed after)")
    ap.add_argument("--keep", action="store_true", help="keep the scratch directory")
    args = ap.parse_args()
    table = Path(args.table)
    if not table.is_file():
        print(f"bench_section4: error: table {table} does not exist; build it first", file=sys.stderr)
        return 2
    work = Path(args.workdir) if args.workdir else Path(tempfile.mkdtemp(prefix="bench_s4_"))
    work.mkdir(parents=True, exist_ok=True)
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    shutil.copytree(ROOT / "workflow", work / "workflow", dirs_exist_ok=True)
    shutil.copy(ROOT / "config.yaml", work / "config.yaml")
    (work / "results/table").mkdir(parents=True, exist_ok=True)
    shutil.copy(table, work / "results/table/table.npz")
    (work / "only_s4.yaml").write_text("paper:\n  stages: [section4]\n")
    cmd = [
        sys.executable,
        "-m",
        "snakemake",
        *TARGETS,
        "--cores",
        str(args.cores),
        "--directory",
        str(work),
        "--configfile",
        str(work / "config.yaml"),
        str(work / "only_s4.yaml"),
    ]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=work, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        print(proc.stderr[-3000:], file=sys.stderr)
        return 1
    summary = (work / "results/paper/reproduction.md").read_text().split("## Claims")[0]
    print(json.dumps({"cores": args.cores, "wall_s": round(wall, 1), "under_5_min": wall < 300}))
    print(summary.strip())
    if not args.keep and not args.workdir:
        shutil.rmtree(work)
    return 0


if __name__ == "__main__":
    sys.exit(main())
