"""Section 5 under several data-order seeds and two roundings: which verdicts does anything but the recipe decide?

Each run trains both Section 5 models (calibrated and context-free) with the study's own
rule for one data-order seed under one floating-point rounding, rolls them out on the
validation objects (never the held-out ones) under the same rounding, and scores them with
the study's own Section 5 code (:mod:`imply.study.section5.robustness`). Printed: every
per-seed target and every Section 5 claim per (seed, rounding), the margin each threshold
target is cleared by in the worst run, self-disagreement's chance test across the runs,
each Table 3 quantity's range, and the learning margin (the first validated epoch at
which the own-calibration r reached 0.9).

The two roundings are two kernel paths of this machine: the study's default (``native``:
PyTorch on the machine's own choice), and on a machine with AVX-512 PyTorch pinned to AVX2
(``avx2``), elsewhere the libraries' pre-AVX2 paths (``sse``: PyTorch's default kernels, MKL
on SSE4.2, oneDNN on SSE4.1), which sum in another order. ``--roundings`` names others:
``threads2`` is the default with two threads.

A candidate recipe is ``--set KEY=VALUE`` on config ``model`` (dotted: ``train.epochs=20``,
``variants.calib.calib_frames=[0,7]``); it is judged here, on validation objects only.

Needs the training inputs::

    snakemake --cores 2 results/features/train.npz results/clips/train.csv results/model/readout_ln.npz \\
        results/features/validation.npz results/clips/validation.csv results/table/table.npz

Usage: ``python benchmarks/s5_robustness.py [--seeds 0,1,2,3] [--set train.epochs=20] [--out /tmp/robust]``
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pandas as pd
import yaml
from kernels_reproducibility import ROOT, fresh_work_folder, missing_inputs

from imply.kernels import environment

# rounding -> (config kernels.pin, environment set from outside, torch threads)
ROUNDINGS = {
    "native": ("numpy-avx2", {}, 1),  # the study's default: PyTorch on this machine's own kernels
    "avx2": ("avx2", {}, 1),
    "sse": (
        "numpy-avx2",
        {"ATEN_CPU_CAPABILITY": "default", "MKL_ENABLE_INSTRUCTIONS": "SSE4_2", "ONEDNN_MAX_CPU_ISA": "SSE41"},
        1,
    ),
    "threads2": ("numpy-avx2", {}, 2),
}


def has_avx512() -> bool:
    try:
        return " avx512f" in Path("/proc/cpuinfo").read_text()
    except OSError:
        return False


def cpu_name() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown CPU"


def set_dotted(tree: dict, key: str, value) -> None:
    """``tree[a][b][c] = value`` for ``key`` 'a.b.c'; every part but the last must exist."""
    parts = key.split(".")
    node = tree
    for part in parts[:-1]:
        if not isinstance(node, dict) or part not in node:
            raise KeyError(f"config model has no {key!r} ({part!r} is not there)")
        node = node[part]
    if parts[-1] not in node:
        raise KeyError(f"config model has no {key!r}")
    node[parts[-1]] = value


def parse_value(text: str):
    value = yaml.safe_load(text)
    if isinstance(value, str):  # YAML 1.1 reads 5e-4 as text
        try:
            return float(value)
        except ValueError:
            pass
    return value


def train_and_roll(
    *,
    variant: str,
    seed: int,
    rounding: str,
    model: dict,
    validate_every: int,
    out: Path,
    roll: bool = True,
    source: Path = ROOT,
) -> dict:
    """The study's model_train rule for one model under one rounding, then (``roll``) its rollouts on the validation
    objects. Returns its history, its rule's CPU seconds (Snakemake's ``benchmark:`` file) and the rollouts' path.

    ``source``: the checkout whose workflow and package run the training (another commit's, to time its recipe with
    its own code; the training inputs are this checkout's)."""
    pin, outside, threads = ROUNDINGS[rounding]
    work = out / f"{rounding}-seed{seed}-{variant}"
    fresh_work_folder(work)
    config = yaml.safe_load((source / "config.yaml").read_text())
    config["kernels"] = {"pin": pin}
    config["model"] = json.loads(json.dumps(model))
    config["model"]["seeds"] = [seed]
    config["model"]["train"]["validate_every"] = validate_every
    config["model"]["resources"]["train_threads"] = threads
    (work / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    env = {k: v for k, v in os.environ.items() if k not in environment("avx2")}
    env.update(environment(pin))
    env.update(outside)
    if source != ROOT:  # that checkout's package before this one's (installed in development mode)
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(source / "src"), env.get("PYTHONPATH")]))
    target = f"results/model/{variant}/seed{seed}"
    cmd = ["snakemake", "-s", str(source / "Snakefile"), "-d", str(work), "--cores", str(threads), "--quiet", "all"]
    cmd += ["--allowed-rules", "model_train", "--", f"{target}/training.json"]
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, cwd=work)
    seconds = time.perf_counter() - t0
    record = run_record(work=work, variant=variant, seed=seed, rounding=rounding, seconds=seconds)
    if not roll:
        return record
    contexts = "own,swap,none" if variant == "calib" else "none"
    subprocess.run(
        [
            "imply",
            "study",
            "model",
            "rollout",
            "--model",
            f"{target}/model.pt",
            "--features",
            "results/features/validation.npz",
        ]
        + ["--clips", "results/clips/validation.csv", "--readout", "results/model/readout_ln.npz"]
        + ["--contexts", contexts, "--derangement-seed", str(model["derangement_seed"]), "--threads", str(threads)]
        + ["-o", f"{target}/validation_rollouts.csv"],
        env=env,
        check=True,
        cwd=work,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    return {**record, "rollouts": str(work / f"{target}/validation_rollouts.csv")}


def run_record(*, work: Path, variant: str, seed: int, rounding: str, seconds: float | None = None) -> dict:
    """One trained model in its work folder: its history and its rule's CPU seconds (Snakemake's ``benchmark:`` file);
    ``seconds`` the training's wall time (default: the rule's own, from the same file)."""
    bench = pd.read_csv(work / f"results/benchmarks/model_train/{variant}-{seed}.tsv", sep="\t")
    target = work / f"results/model/{variant}/seed{seed}"
    return {
        "variant": variant,
        "seed": seed,
        "rounding": rounding,
        "train_seconds": round(float(bench["s"].iloc[0]) if seconds is None else seconds, 1),
        "cpu_seconds": round(float(bench["cpu_time"].iloc[0]), 1),
        "history": json.loads((target / "training.json").read_text())["history"],
    }


def already_trained(*, variant: str, seed: int, rounding: str, out: Path) -> dict:
    """What :func:`train_and_roll` returned for a run whose outputs are in ``out`` already."""
    work = out / f"{rounding}-seed{seed}-{variant}"
    record = run_record(work=work, variant=variant, seed=seed, rounding=rounding)
    return {**record, "rollouts": str(work / f"results/model/{variant}/seed{seed}/validation_rollouts.csv")}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0,1,2,3", help="data-order seeds (comma-separated; at least 4 asked)")
    ap.add_argument(
        "--roundings",
        default="auto",
        help=f"comma-separated of {', '.join(ROUNDINGS)}; auto: native, and avx2 (AVX-512 machines) or sse",
    )
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a config model key (dotted)")
    ap.add_argument("--validate-every", type=int, default=2, help="epochs between validations (the learning margin)")
    ap.add_argument("--jobs", type=int, default=2, help="trainings side by side")
    ap.add_argument("--out", type=Path, default=Path("/tmp/s5-robustness"))
    ap.add_argument(
        "--score-only",
        action="store_true",
        help="score the trainings and rollouts already in --out (the same seeds, roundings and recipe) again",
    )
    ap.add_argument(
        "--calib-only",
        action="store_true",
        help="train the calibrated models alone and print their validation histories (a quick look at a candidate)",
    )
    ap.add_argument(
        "--variants",
        default="calib,nocalib",
        help="the models to train (comma-separated); with --score-only every model of the runs must be in --out, so "
        "a candidate for one variant is judged beside the other's runs copied there",
    )
    args = ap.parse_args(argv)
    if missing_inputs():
        return 2
    seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    roundings = ["native", "avx2" if has_avx512() else "sse"] if args.roundings == "auto" else args.roundings.split(",")
    bad = [r for r in roundings if r not in ROUNDINGS]
    if bad:
        ap.error(f"--roundings: unknown {bad[0]!r} (known: {', '.join(ROUNDINGS)})")
    model = yaml.safe_load((ROOT / "config.yaml").read_text())["model"]
    for item in args.set:
        key, sep, text = item.partition("=")
        if not sep:
            ap.error(f"--set {item!r}: expected KEY=VALUE")
        try:
            set_dotted(model, key, parse_value(text))
        except KeyError as exc:
            ap.error(f"--set {item!r}: {exc.args[0]}")
    args.out.mkdir(parents=True, exist_ok=True)
    # the calibrated models first: they take longest, so the pool ends with the short ones
    variants = ["calib"] if args.calib_only else [v for v in args.variants.split(",") if v.strip()]
    unknown = [v for v in variants if v not in model["variants"]]
    if unknown:
        ap.error(f"--variants: unknown {unknown[0]!r} (config model.variants: {', '.join(model['variants'])})")
    jobs = [(v, s, r) for v in variants for r in roundings for s in seeds]
    t0 = time.perf_counter()

    def one(job):
        variant, seed, rounding = job
        done = train_and_roll(
            variant=variant, seed=seed, rounding=rounding, model=model, validate_every=args.validate_every, out=args.out
        )
        print(f"  {variant} seed {seed} {rounding}: {done['train_seconds']} s", flush=True)
        return done

    if args.score_only:
        trained = [already_trained(variant=v, seed=s, rounding=r, out=args.out) for v, s, r in jobs]
    else:
        with ThreadPoolExecutor(args.jobs) as pool:
            trained = list(pool.map(one, jobs))
    wall = time.perf_counter() - t0
    if args.calib_only:
        for t in trained:
            track = ", ".join(f"{h['epoch']}: {h['own_track']:.2f}" for h in t["history"] if "own_track" in h)
            last = t["history"][-1]
            print(
                f"seed {t['seed']} {t['rounding']} ({t['train_seconds']} s): own r by epoch {track}; last: error "
                f"{last['own_error']:.3f}, anchored prefers own {last['own_lt_swap_anchored']:.1f}%, self "
                f"{last['own_lt_swap_self']:.1f}%"
            )
        return 0

    from imply.cli.section5 import section5_part
    from imply.models.object_blind import typical_slide_of_clips
    from imply.score import ScoreConfig
    from imply.study.section5.robustness import robustness_report, run_outcome
    from imply.table import PushTable

    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    score = ScoreConfig(**{k: v for k, v in config["score"].items() if k in ("grid", "readout_floor")})
    scorer = score.scorer(PushTable.load(ROOT / "results/table/table.npz"))
    typical = typical_slide_of_clips(pd.read_csv(ROOT / "results/clips/train.csv"))
    by = {(t["variant"], t["seed"], t["rounding"]): t for t in trained}
    for job in [(v, s, r) for v in ("calib", "nocalib") for r in roundings for s in seeds]:
        if job not in by:  # the other variant's runs, trained before into --out
            try:
                by[job] = already_trained(variant=job[0], seed=job[1], rounding=job[2], out=args.out)
            except FileNotFoundError:
                ap.error(f"--variants: {job[0]} seed {job[1]} {job[2]} is neither trained now nor in {args.out}")
            trained.append(by[job])
    runs = []
    for rounding in roundings:
        for seed in seeds:
            calib, nocalib = by[("calib", seed, rounding)], by[("nocalib", seed, rounding)]
            runs.append(
                run_outcome(
                    seed=seed,
                    rounding=rounding,
                    calib=pd.read_csv(calib["rollouts"]),
                    nocalib=pd.read_csv(nocalib["rollouts"]),
                    history=calib["history"],
                    scorer=scorer,
                    typical=typical,
                    selection_seed=model["selection_seed"],
                    part=section5_part,
                )
            )
    recipe = ", ".join(args.set) or "the config's"
    report = robustness_report(runs, recipe=recipe)
    seconds = {
        v: sum(t["train_seconds"] for t in trained if t["variant"] == v) / (len(seeds) * len(roundings))
        for v in ("calib", "nocalib")
    }
    what = "read back from --out" if args.score_only else f"the whole benchmark {wall / 60:.1f} min"
    report += (
        f"\nOn {cpu_name()}, {args.jobs} trainings side by side, one thread each: a calibrated training took "
        f"{seconds['calib']:.0f} s on average, a context-free one {seconds['nocalib']:.0f} s (validating every "
        f"{args.validate_every} epochs; {what}).\n"
    )
    (args.out / "robustness.md").write_text(report)
    (args.out / "runs.json").write_text(
        json.dumps(
            {
                "recipe": args.set,
                "cpu": cpu_name(),
                "trainings": [{k: v for k, v in t.items() if k != "history"} for t in trained],
                "runs": [
                    {
                        "seed": r.seed,
                        "rounding": r.rounding,
                        "numbers": r.numbers,
                        "claims": r.claims,
                        "learned_at": r.learned_at,
                        "epochs": r.epochs,
                    }
                    for r in runs
                ],
            },
            indent=1,
        )
    )
    print(report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
