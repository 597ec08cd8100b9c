"""The other-contact benchmark on a development set: where the diagnostic's settings are chosen, never on the
workflow's evaluation set.

The development set has the design of config ``gap.contact_benchmark`` with another seed
(default 7117; the evaluation set is the config's 2424): ``imply gap generate`` writes it,
``imply gap diagnose-many`` diagnoses it in two shards (one process per core), and
:func:`imply.diagnose.benchmark.score_contact_cases` scores it exactly as the workflow scores
the evaluation set. ``--set KEY=VALUE`` changes one diagnostic option (config ``gap.diagnose``);
``--ignore-measured`` leaves the logs' weighed masses out. The logs are generated once per
folder and reused.

Run: python benchmarks/gap_contact_dev.py --out /tmp/contact-dev [--seed 7117] [--set discrepancy_sd=0.3]
     [--name LABEL] [--cases]

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

from imply.diagnose.benchmark import find_summaries, score_contact_cases

ROOT = Path(__file__).resolve().parents[1]
METRICS = ("null_no_library", "null_discrepancy", "named", "named_any", "wrong_mechanism")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, required=True, help="folder for the development logs and their diagnoses")
    ap.add_argument("--seed", type=int, default=7117, help="the development set's seed (not the config's 2424)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a gap.diagnose option")
    ap.add_argument("--ignore-measured", action="store_true", help="leave the logs' weighed masses out")
    ap.add_argument("--name", default="config", help="label of this run (its diagnoses' folder)")
    ap.add_argument("--cases", action="store_true", help="print every log's verdict")
    ap.add_argument("--table", type=Path, default=ROOT / "results/table/table.npz")
    ap.add_argument("--effect-tables", type=Path, default=ROOT / "results/gap/effect_tables")
    args = ap.parse_args(argv)

    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    design = dict(config["gap"]["contact_benchmark"], seed=args.seed)
    if args.seed == config["gap"]["contact_benchmark"]["seed"]:
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
        subprocess.run(["imply", "gap", "generate", "--table", str(args.table), "--contact-bench-json",
                        json.dumps(design), "--logs", str(logs), "--sealed", str(labels), "--accuracy",
                        str(args.out / "accuracy.json"), "--threads", "2"], check=True)  # fmt: skip
    files = sorted(str(p) for p in logs.glob("*.csv"))
    run = args.out / "runs" / args.name
    t0 = time.perf_counter()
    procs = []
    for k, part in enumerate((files[::2], files[1::2])):
        cmd = ["imply", "gap", "diagnose-many", *part, "--table", str(args.table), "--effect-grid-json", grid,
               "--options-json", json.dumps(options), "--cache-dir", str(args.effect_tables), "--threads", "1",
               "--force", "-o", str(run / f"shard{k}")]  # fmt: skip
        if args.ignore_measured:
            cmd.append("--ignore-measured")
        procs.append(subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
    if any(p.wait() for p in procs):
        print("a diagnose-many shard failed", file=sys.stderr)
        return 1
    seconds = time.perf_counter() - t0
    sealed = json.loads(labels.read_text())
    summaries = find_summaries(sealed, [run / "shard0", run / "shard1"])
    result = score_contact_cases(sealed, summaries, targets=design["targets"], min_size_sd=design["min_size_sd"])
    print(f"{args.name}: {len(files)} development logs (seed {args.seed}), diagnosed in {seconds:.0f} s")
    for key in METRICS:
        print(f"  {key:18s} {result[key]:.3f} (n {result['n_' + key]}); MuJoCo contact "
              f"{result[key + '_mujoco']:.2f}, Bullet {result[key + '_bullet']:.2f}")  # fmt: skip
    if args.cases:
        frame = pd.DataFrame(result["cases"])
        cols = ["case", "group", "engine", "effects", "verdict_kind", "causes", "alternatives"]
        print(frame[cols].to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
