"""The gap benchmarks on development sets: where the diagnostic's settings are chosen, never on the workflow's
evaluation sets.

The development set has the design of config ``gap.contact_benchmark`` with another seed
(default 7117; the evaluation set is the config's): ``imply study gap generate`` writes it,
``imply study gap diagnose-many`` diagnoses it in two shards (one process per core), and
:func:`imply.realworld.benchmark.score_contact_cases` scores it exactly as the workflow scores
the evaluation set. ``--main`` does the same for the main benchmark (config ``gap.benchmark``,
development seed 1001; the evaluation set is the config's), scored by
:func:`imply.realworld.benchmark.score_cases`. ``--set KEY=VALUE`` changes one diagnostic
option (config ``gap.diagnose``); ``--ignore-measured`` leaves the logs' weighed masses out; ``--closed-loop``
then runs the closed loop on the development logs with several contenders (``imply study gap closed-loop``, two
shards) and scores it as the workflow does (:func:`imply.realworld.closed_loop.score_closed_loop`). The logs are
generated once per folder and reused.

Run: python benchmarks/gap_contact_dev.py --out /tmp/contact-dev [--seed 7117] [--set discrepancy_sd=0.3]
     [--name LABEL] [--cases] [--closed-loop]
     python benchmarks/gap_contact_dev.py --main --out /tmp/main-dev [--name LABEL]

Needs results/table/table.npz and results/gap/effect_tables (``snakemake --cores 2
results/gap/effect_tables``). Prints the four target metrics with their counts, per engine.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import pandas as pd
import yaml

from imply.realworld.benchmark import find_summaries, score_cases, score_contact_cases, visible_sizes

ROOT = Path(__file__).resolve().parents[1]
METRICS = (
    "null_no_library",
    "among_named",
    "one_cause",
    "single_right",
    "told_right",
    "named",
    "wrong_single",
    "wrong_mechanism",
)
MAIN_METRICS = {
    "false_alarm": "n_null",
    "top1_big": "n_big",
    "both_named_big": "n_double_big",
    "none_recall_outside": "n_outside",
    "magnitude_rel_error_median": "n_magnitudes",
    "shrinkage_median": "n_shrinkage",
}  # metric: its count


def run_shards(cmds: list[list[str]]) -> bool:
    """Run ``imply`` commands side by side (one per core); False, with a line on stderr, if any failed."""
    procs = [subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL) for cmd in cmds]
    failed = [cmd[2] for cmd, p in zip(cmds, procs, strict=True) if p.wait()]
    if failed:
        print(f"a {failed[0]} shard failed", file=sys.stderr)
    return not failed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, required=True, help="folder for the development logs and their diagnoses")
    ap.add_argument("--main", action="store_true", help="the main benchmark (gap.benchmark) instead")
    ap.add_argument("--seed", type=int, default=None, help="the development set's seed (default 7117; --main 1001)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a gap.diagnose option")
    ap.add_argument("--ignore-measured", action="store_true", help="leave the logs' weighed masses out")
    ap.add_argument("--name", default="config", help="label of this run (its diagnoses' folder)")
    ap.add_argument("--cases", action="store_true", help="print every log's verdict")
    ap.add_argument("--closed-loop", action="store_true", help="run and score the closed loop (other contact only)")
    ap.add_argument("--table", type=Path, default=ROOT / "results/table/table.npz")
    ap.add_argument("--effect-tables", type=Path, default=ROOT / "results/gap/effect_tables")
    ap.add_argument("--effects", help="comma-separated candidate effects (default: the config's, or the whole library)")
    args = ap.parse_args(argv)

    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    section = "benchmark" if args.main else "contact_benchmark"
    if args.seed is None:
        args.seed = 1001 if args.main else 7117
    design = dict(config["gap"][section], seed=args.seed)
    if args.seed == config["gap"][section]["seed"]:
        ap.error(f"--seed {args.seed} is the evaluation set's seed; choose settings on another")
    options = dict(config["gap"]["diagnose"])
    for item in args.set:
        key, eq, text = item.partition("=")
        if not eq or key not in options:
            ap.error(f"--set {item!r}: expected KEY=VALUE with KEY one of {', '.join(sorted(options))}")
        options[key] = yaml.safe_load(text)  # numbers, booleans, null, lists
    grid = json.dumps(config["gap"]["effect_grid"])

    logs, labels = args.out / "logs", args.out / "labels.json"
    if not labels.exists():
        subprocess.run(
            [
                "imply",
                "gap",
                "generate",
                "--table",
                str(args.table),
                "--bench-json" if args.main else "--contact-bench-json",
                json.dumps(design),
                "--logs",
                str(logs),
                "--sealed",
                str(labels),
                "--accuracy",
                str(args.out / "accuracy.json"),
                "--threads",
                "2",
            ],
            check=True,
        )
    files = sorted(str(p) for p in logs.glob("*.csv") if not p.name.endswith(".track.csv"))
    run = args.out / "runs" / args.name
    t0 = time.perf_counter()
    cmds = [
        [
            "imply",
            "gap",
            "diagnose-many",
            *part,
            "--table",
            str(args.table),
            "--effect-grid-json",
            grid,
            "--options-json",
            json.dumps(options),
            "--cache-dir",
            str(args.effect_tables),
            "--threads",
            "1",
            "--force",
            "-o",
            str(run / f"shard{k}"),
        ]
        + (["--ignore-measured"] if args.ignore_measured else [])
        + (["--effects", args.effects] if args.effects else [])
        for k, part in enumerate((files[::2], files[1::2]))
    ]
    if not run_shards(cmds):
        return 1
    seconds = time.perf_counter() - t0
    sealed = json.loads(labels.read_text())
    summaries = find_summaries(sealed, [run / "shard0", run / "shard1"])
    if args.main:
        return _print_main(args, design, sealed, summaries, seconds, len(files))
    result = score_contact_cases(sealed, summaries, targets=design["targets"], min_size_sd=design["min_size_sd"])
    print(f"{args.name}: {len(files)} development logs (seed {args.seed}), diagnosed in {seconds:.0f} s")
    for key in METRICS:
        print(
            f"  {key:18s} {result[key]:.3f} (n {result['n_' + key]}); MuJoCo contact "
            f"{result[key + '_mujoco']:.2f}, Bullet {result[key + '_bullet']:.2f}"
        )
    print(
        f"  contenders         mean {result['contenders_mean']:.2f}, largest {result['contenders_max']}; one cause "
        f"right {result['one_cause_right']:.3f} (n {result['n_one_cause_right']})"
    )
    if args.cases:
        frame = pd.DataFrame(result["cases"])
        cols = ["case", "group", "engine", "effects", "identification", "causes", "contenders"]
        print(frame[cols].to_string(index=False))
    if args.closed_loop:
        return _closed_loop(args, design, options, grid, run, sealed)
    return 0


def _closed_loop(args: argparse.Namespace, design: dict, options: dict, grid: str, run: Path, sealed: dict) -> int:
    """The closed loop on the development run ``run``'s reports, scored as the workflow scores it."""
    from imply.realworld.closed_loop import score_closed_loop

    loop = args.out / "closed" / args.name
    cmds = [
        [
            "imply",
            "gap",
            "closed-loop",
            "--contact-bench-json",
            json.dumps(design),
            "--logs",
            str(args.out / "logs"),
            "--reports",
            str(run / f"shard{k}"),
            "-o",
            str(loop / f"shard{k}"),
            "--table",
            str(args.table),
            "--cache-dir",
            str(args.effect_tables),
            "--effect-grid-json",
            grid,
            "--options-json",
            json.dumps(options),
            "--threads",
            "1",
            "--no-plots",
            "--force",
        ]
        for k in range(2)
    ]
    if not run_shards(cmds):
        return 1
    result = score_closed_loop(
        sealed,
        [loop / "shard0", loop / "shard1"],
        within=design["targets"]["magnitude_within"],
        min_size_sd=design["min_size_sd"],
    )
    for arm in ("next", "random"):
        r = result[arm]
        print(
            f"  closed loop, {arm:6s} one cause right {r['one_cause_right']:.3f} (n {r['n_single']}), told the "
            f"cause {r['told_right']:.3f}; null logs clear {r['null_no_library']:.3f} (n {r['n_null']}); outside "
            f"stated {r['wrong_single']:.3f} (n {r['n_outside']}); contenders {r['contenders_mean']:.2f}"
        )
    return 0


def _print_main(
    args: argparse.Namespace, design: dict, sealed: dict, summaries: dict, seconds: float, n_files: int
) -> int:
    from imply.cli.common import load_table
    from imply.realworld.cases import BenchmarkConfig

    config = BenchmarkConfig.from_dict(design, "gap.benchmark")
    accuracy = json.loads((args.out / "accuracy.json").read_text())
    sizes = visible_sizes(sealed, load_table(args.table), progress=False)
    result = score_cases(sealed, summaries, sizes, config=config, accuracy=accuracy)
    print(f"{args.name}: {n_files} development logs (seed {args.seed}), diagnosed in {seconds:.0f} s")
    for key, n in MAIN_METRICS.items():
        print(f"  {key:28s} {result[key]:.3f} (n {result[n]})")
    if args.cases:
        frame = pd.DataFrame(result["cases"])
        print(frame[["case", "group", "effects", "accepted", "correct"]].to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
