"""The gap diagnoses' time against a baseline commit's, in the same run, and whether they say the same.

Diagnoses a sample of the gap benchmarks' logs (``imply study gap diagnose-many``, the workflow's settings
from config.yaml: the default options, and with ``--observed`` the pusher's speed and the box's track
too) with this checkout's code and with the code of a baseline commit (a git worktree, imported ahead of
the installed package), alternating the order over ``--repeats`` rounds. Prints each run's wall time and
the children's peak memory, the medians and their ratio, and compares the two codes' reports file by
file: every byte the same but the seconds each diagnosis took.

Run: python benchmarks/gap_diagnose_speed.py [--baseline REV] [--logs 8] [--contact] [--observed] [--repeats 2]
     [--baseline-lacks use_probes,free_launch]  (a baseline of an earlier design: its own options only)
     [--log-dir /tmp/main-dev/logs]  (another folder of logs, a development set's, say)
Needs the gap stage's logs (or --log-dir) and effect tables (snakemake --cores 2 results/gap/reports/shard0).
"""

from __future__ import annotations

import argparse
import filecmp
import json
import resource
import tempfile
from pathlib import Path

import yaml
from baseline_tree import ROOT, ab_rounds, baseline_tree, print_medians, timed_imply

BASELINE = "219b579"  # before the fits read each table once per point set and merged their steps' reads
OBSERVED = {"use_pusher_speed": True, "use_track": True}


def diagnose(src: Path, logs: list[Path], options: dict, config: dict, out: Path) -> float:
    """Wall seconds of one ``imply study gap diagnose-many`` of ``logs`` with the package under ``src``."""
    gap = config["gap"]
    args = [
        "gap",
        "diagnose-many",
        *map(str, logs),
        "--table",
        str(ROOT / "results/table/table.npz"),
        "--effect-grid-json",
        json.dumps(gap["effect_grid"]),
        "--options-json",
        json.dumps(options),
        "--cache-dir",
        str(ROOT / "results/gap/effect_tables"),
        "--threads",
        "1",
        "--no-plots",
        "-o",
        str(out),
    ]
    return timed_imply(src, args, gap.get("candidates"))


def differences(a: Path, b: Path) -> list[str]:
    """Files of report folders ``a`` and ``b`` that differ, beyond the seconds a diagnosis took."""
    out = []
    for fa in sorted(a.rglob("*")):
        if not fa.is_file():
            continue
        fb = b / fa.relative_to(a)
        if not fb.is_file():
            out.append(f"{fa.relative_to(a)}: missing")
        elif fa.name == "summary.json":
            da, db = (json.loads(p.read_text()) for p in (fa, fb))
            da.pop("seconds", None), db.pop("seconds", None)
            if da != db:
                out.append(str(fa.relative_to(a)))
        elif not filecmp.cmp(fa, fb, shallow=False):
            out.append(str(fa.relative_to(a)))
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--baseline", default=BASELINE, help="git revision whose diagnoses are the baseline")
    ap.add_argument("--logs", type=int, default=8, help="logs diagnosed per run, spread over the benchmark")
    ap.add_argument("--contact", action="store_true", help="the other-contact benchmark's logs")
    ap.add_argument("--observed", action="store_true", help="with the pusher's measured speed and the box's track")
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument(
        "--log-dir",
        type=Path,
        help="the logs' folder (default: the gap stage's, or with --contact its other-contact set)",
    )
    ap.add_argument(
        "--baseline-lacks",
        default="",
        metavar="KEY,...",
        help="options the baseline does not know, left out of its runs (its design without them: the reports then "
        "differ, and the ratio is the new design's cost)",
    )
    args = ap.parse_args(argv)
    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    folder = args.log_dir or ROOT / ("results/gap/contact/logs" if args.contact else "results/gap/logs")
    every = sorted(p for p in folder.glob("*.csv") if not p.name.endswith(".track.csv"))
    if not every:
        raise SystemExit(f"no logs in {folder}: run the gap stage first")
    logs = every[:: max(1, len(every) // args.logs)][: args.logs]
    options = {**config["gap"]["diagnose"], **(OBSERVED if args.observed else {})}
    lacks = [k for k in args.baseline_lacks.split(",") if k]
    baseline_options = {k: v for k, v in options.items() if k not in lacks}
    times: dict[str, list[float]] = {"baseline": [], "current": []}
    with tempfile.TemporaryDirectory() as tmp, baseline_tree(args.baseline) as tree:
        for r, which in ab_rounds(args.repeats):
            src = tree / "src" if which == "baseline" else ROOT / "src"
            opts = baseline_options if which == "baseline" else options
            wall = diagnose(src, logs, opts, config, Path(tmp) / f"{which}-{r}")
            times[which].append(wall)
            peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0
            print(f"round {r + 1} {which:8s} {wall:6.1f} s for {len(logs)} logs  (peak RSS so far {peak:.0f} MiB)")
        changed = differences(Path(tmp) / "baseline-0", Path(tmp) / "current-0")
    print_medians(times, args.baseline)
    print("reports: the same but the seconds" if not changed else f"reports differ: {', '.join(changed[:10])}")
    return 1 if changed else 0


if __name__ == "__main__":
    raise SystemExit(main())
