"""How far rounding moves the Section 5 models: each trained twice, on two floating-point paths, judged on validation.

Each of the four Section 5 models (calibrated and not, data-order seeds 0 and 1) is trained
with the study's own rule and recipe (config ``model.train``) twice: once with every library
on its AVX-512 code path (this machine's own choice, ``kernels.pin: native``) and once pinned
to AVX2 (the study's default). The two runs start from the same weights and see the same
batches; only the order of floating-point sums differs. Printed: the last epoch's validation
numbers of both runs (validation objects only, never the held-out ones) and how far they move.
A recipe whose seed moves its own-calibration tracking r by more than 0.05 is decided by
rounding.

Needs the training inputs (see ``benchmarks/kernels_reproducibility.py``).

``--set KEY=VALUE`` changes one key of config ``model.train`` (a candidate recipe, judged here on
the validation objects only); ``--variants calib`` trains the calibrated models alone.

Usage: ``python benchmarks/recipe_spread.py [--out /tmp/spread] [--epochs 40] [--set lr=5e-4] [--variants calib]``
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from kernels_reproducibility import ROOT, missing_inputs, run

KEYS = {
    "calib": ("own_track", "own_error", "own_lt_swap_anchored", "swap_track", "none_track"),
    "nocalib": ("none_track", "none_error"),
}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("/tmp/spread"))
    ap.add_argument("--epochs", type=int, default=None, help="default: the study's (config model.train.epochs)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a config model.train key")
    ap.add_argument("--variants", default="calib,nocalib", help="comma-separated: calib, nocalib")
    args = ap.parse_args(argv)
    if missing_inputs():
        return 2
    import yaml

    train = yaml.safe_load((ROOT / "config.yaml").read_text())["model"]["train"]
    overrides = {}
    for item in args.set:
        key, sep, text = item.partition("=")
        if not sep or key not in train:
            ap.error(f"--set {item!r}: expected KEY=VALUE with KEY one of {', '.join(sorted(train))}")
        value = yaml.safe_load(text)
        if isinstance(value, str):  # YAML 1.1 reads 5e-4 as text
            try:
                value = float(value)
            except ValueError:
                pass
        overrides[key] = value
    epochs = args.epochs or int(overrides.get("epochs", train["epochs"]))
    variants = [v for v in args.variants.split(",") if v]
    bad = [v for v in variants if v not in KEYS]
    if bad:
        ap.error(f"--variants: unknown {', '.join(bad)} (known: calib, nocalib)")
    jobs = [(variant, seed, pin) for variant in variants for seed in (0, 1) for pin in ("native", "avx2")]

    def one(job):
        variant, seed, pin = job
        return run(
            f"{variant} seed{seed} {pin}",
            pin,
            {},
            epochs=epochs,
            seed=seed,
            out=args.out,
            variant=variant,
            keys=KEYS[variant],
            train=overrides,
        )

    # two jobs at a time: the study's training runs one thread each, two side by side
    with ThreadPoolExecutor(2) as pool:
        rows = list(pool.map(one, jobs))
    (args.out / "spread.json").write_text(json.dumps(rows, indent=1))
    by = {r["name"]: r for r in rows}
    recipe = ", ".join(f"{k}={v}" for k, v in overrides.items()) or "the study's recipe"
    print(
        f"Section 5 models ({recipe}), last epoch ({epochs}) on the validation objects: AVX-512 (native) against "
        "AVX2 (pinned)\n"
    )
    print("| model | quantity | AVX-512 | AVX2 | moved |")
    print("|---|---|---|---|---|")
    worst = {}
    for variant in variants:
        for seed in (0, 1):
            a, b = by[f"{variant} seed{seed} native"], by[f"{variant} seed{seed} avx2"]
            for k in KEYS[variant]:
                x, y = a["validation"].get(k), b["validation"].get(k)
                if x is None or y is None:
                    continue
                print(f"| {variant} seed {seed} | {k} | {x:.3f} | {y:.3f} | {abs(x - y):.3f} |")
                if k == ("own_track" if variant == "calib" else "none_track"):
                    worst[f"{variant} seed {seed}"] = abs(x - y)
    print(
        "\nhow far each seed's tracking r moved (own calibration; none for the uncalibrated): "
        + ", ".join(f"{k} {v:.3f}" for k, v in worst.items())
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
