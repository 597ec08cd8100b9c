"""The effect tables' build time with the track summaries, against the build before them, in the same run.

Builds the gap stage's effect tables (``imply study gap tables``, the workflow's settings from
config.yaml, into an empty cache each time) with this checkout's code and with the code of
a baseline commit (a git worktree, imported ahead of the installed package), alternating
the order over ``--repeats`` rounds, and prints each build's wall time and peak memory,
their medians and the ratio. The default baseline is the last commit whose tables held
the stop time and the pusher's speed alone (format 4).

Run: python benchmarks/effect_tables_build.py [--baseline REV] [--repeats 2] [--threads 2]
Needs results/table/table.npz.
"""

from __future__ import annotations

import argparse
import json
import resource
import tempfile
from pathlib import Path

import yaml
from baseline_tree import ROOT, ab_rounds, baseline_tree, print_medians, timed_imply

BASELINE = "df94700"  # format 4: stop time and pusher speed, no track summaries


# options the baseline does not know (they change no table)
NEWER_OPTIONS = ("use_track", "track_noise_sd")


def build(src: Path, table: Path, config: dict, threads: int, out: Path, *, baseline: bool) -> tuple[float, float]:
    """Wall seconds and peak RSS (MiB) of one ``imply study gap tables`` with the package under ``src``."""
    gap = config["gap"]
    options = {k: v for k, v in gap["diagnose"].items() if not (baseline and k in NEWER_OPTIONS)}
    args = [
        "gap",
        "tables",
        "--table",
        str(table),
        "--effect-grid-json",
        json.dumps(gap["effect_grid"]),
        "--options-json",
        json.dumps(options),
        "--threads",
        str(threads),
        "-o",
        str(out),
    ]
    wall = timed_imply(src, args, gap.get("candidates"))
    # the children's ru_maxrss is the largest of any child so far: a smaller later build reads as the earlier peak
    return wall, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", default=BASELINE, help="git revision whose build is the baseline")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--table", type=Path, default=ROOT / "results/table/table.npz")
    args = ap.parse_args(argv)
    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    times: dict[str, list[float]] = {"baseline": [], "current": []}
    with tempfile.TemporaryDirectory() as tmp, baseline_tree(args.baseline) as tree:
        for r, which in ab_rounds(args.repeats):
            src = tree / "src" if which == "baseline" else ROOT / "src"
            wall, peak = build(
                src, args.table, config, args.threads, Path(tmp) / f"{which}-{r}", baseline=which == "baseline"
            )
            times[which].append(wall)
            print(f"round {r + 1} {which:8s} {wall:7.1f} s  (peak RSS of any build so far {peak:.0f} MiB)")
    print_medians(times, args.baseline)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
