"""The Section 5 trainings' CPU time: the config's recipe against another, side by side in one run.

Each recipe's four trainings (calibrated and context-free, data-order seeds 0 and 1) run with
the study's own rule (Snakemake's ``benchmark:`` file gives each job's CPU seconds), two at a
time and alternating between the recipes, so both see the same machine and the same
neighbour. Whole trainings only: a few epochs scaled up would count each job's start-up (Snakemake,
imports, the features) many times over.

The other recipe is ``--before KEY=VALUE`` on config ``model`` (dotted keys, as in
``benchmarks/s5_robustness.py``); ``--before-pin`` its kernel pin. Or ``--before-source DIR``: a
checkout of another commit (``git worktree add DIR COMMIT``), whose own config, workflow and
package train the other recipe, so that a change of the training code is timed too.

Usage: ``python benchmarks/s5_training_time.py --before-source /tmp/before`` or
``python benchmarks/s5_training_time.py --before train.epochs=60 --before-pin avx2 ...``
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import yaml
from kernels_reproducibility import missing_inputs
from s5_robustness import ROOT, ROUNDINGS, cpu_name, parse_value, set_dotted, train_and_roll


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--before", action="append", default=[], metavar="KEY=VALUE", help="the other recipe (config model)"
    )
    ap.add_argument("--before-pin", default=None, help="the other recipe's kernel pin (default: the config's)")
    ap.add_argument(
        "--before-source",
        type=Path,
        default=None,
        help="another commit's checkout: its config's recipe and pin, trained by its own workflow and package",
    )
    ap.add_argument("--out", type=Path, default=Path("/tmp/s5-training-time"))
    args = ap.parse_args(argv)
    if missing_inputs():
        return 2
    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    after = config["model"]
    source = {"after": ROOT, "before": (args.before_source or ROOT).resolve()}
    before_config = yaml.safe_load((source["before"] / "config.yaml").read_text())
    before = json.loads(json.dumps(before_config["model"]))
    for item in args.before:
        key, _, text = item.partition("=")
        set_dotted(before, key, parse_value(text))
    pins = {"after": config["kernels"]["pin"], "before": args.before_pin or before_config["kernels"]["pin"]}
    for name, pin in pins.items():
        ROUNDINGS[f"{name}-pin"] = (pin, {}, 1)
    recipes = {"after": after, "before": before}
    jobs = [
        (name, variant, seed) for variant in ("calib", "nocalib") for seed in (0, 1) for name in ("before", "after")
    ]

    def one(job):
        name, variant, seed = job
        model = recipes[name]
        done = train_and_roll(
            variant=variant,
            seed=seed,
            rounding=f"{name}-pin",
            model=model,
            validate_every=model["train"]["validate_every"],
            out=args.out / name,
            roll=False,
            source=source[name],
        )
        return name, variant, seed, done["cpu_seconds"]

    with ThreadPoolExecutor(2) as pool:
        rows = list(pool.map(one, jobs))
    cpu = {(name, variant, seed): c for name, variant, seed, c in rows}
    total = {}
    print(f"Section 5 trainings, CPU seconds on {cpu_name()}, two side by side on one thread each")
    print(f"before: {source['before']} (kernels {pins['before']}); after: {ROOT} (kernels {pins['after']})\n")
    print("| training | before | after | after / before |")
    print("|---|---|---|---|")
    for variant in ("calib", "nocalib"):
        for seed in (0, 1):
            whole = {name: cpu[(name, variant, seed)] for name in ("before", "after")}
            for name, c in whole.items():
                total[name] = total.get(name, 0.0) + c
            print(
                f"| {variant} seed {seed} | {whole['before']:.0f} | {whole['after']:.0f} | "
                f"{whole['after'] / whole['before']:.2f} |"
            )
    print(
        f"| the four | {total['before'] / 60:.1f} min | {total['after'] / 60:.1f} min | "
        f"{total['after'] / total['before']:.2f} |"
    )
    (args.out / "training_time.json").write_text(json.dumps({"rows": rows, "total_cpu_s": total}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
