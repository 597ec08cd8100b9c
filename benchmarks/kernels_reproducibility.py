"""The kernel pin, measured: the study's own training job under each instruction set, with and without the pin.

One machine stands in for two: "this machine" runs with whatever its libraries pick (AVX-512
here), "an AVX2 machine" is emulated by forcing every library to its AVX2 code path from
outside (PyTorch, MKL, oneDNN, NumPy, OpenBLAS), as a laptop would pick it. Each condition
runs the study's training rule (Snakemake, the workflow's own command and environment) for
a few epochs in a work folder of its own that links the study's inputs, then compares the
trained weights' bytes and the validation errors, and prints the pin's cost in time.

Needs the training inputs built first::

    snakemake --cores 2 results/features/train.npz results/clips/train.csv results/model/readout_ln.npz \
        results/features/validation.npz results/clips/validation.csv results/table/table.npz

Usage: ``python benchmarks/kernels_reproducibility.py [--epochs 3] [--seed 1] [--out /tmp/kernels]``
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from imply.kernels import environment

ROOT = Path(__file__).resolve().parents[1]
INPUTS = [
    "results/features/train.npz",
    "results/clips/train.csv",
    "results/model/readout_ln.npz",
    "results/features/validation.npz",
    "results/clips/validation.csv",
    "results/table/table.npz",
]


def missing_inputs() -> bool:
    """True (after saying which, on stderr) when a training input is not built yet."""
    missing = [p for p in INPUTS if not (ROOT / p).exists()]
    if missing:
        print("missing training inputs (build them first, see the module doc): " + ", ".join(missing), file=sys.stderr)
    return bool(missing)


def fresh_work_folder(work: Path) -> None:
    """``work`` emptied, with the training inputs linked in from this checkout's results."""
    shutil.rmtree(work, ignore_errors=True)
    for rel in INPUTS:
        (work / rel).parent.mkdir(parents=True, exist_ok=True)
        os.symlink(ROOT / rel, work / rel)


# an AVX2 machine: every library on its AVX2 code path, as the pin sets it, less MKL's reproducibility mode
AVX2_MACHINE = {k: v for k, v in environment("avx2").items() if k != "MKL_CBWR"}
CONDITIONS = [  # (name, kernels.pin, the machine's own choice)
    ("native, this machine", "native", {}),
    ("native, AVX2 machine", "native", AVX2_MACHINE),
    ("pinned, this machine", "avx2", {}),
    ("pinned, this machine again", "avx2", {}),
    ("pinned, AVX2 machine", "avx2", AVX2_MACHINE),
    ("pinned, AVX-512 asked from outside", "avx2", {"ATEN_CPU_CAPABILITY": "avx512"}),
]


def weights_digest(path: Path) -> str:
    import torch

    state = torch.load(path, map_location="cpu", weights_only=True)["model"]
    h = hashlib.sha256()
    for k in sorted(state):
        v = state[k]
        if hasattr(v, "numpy"):
            h.update(k.encode())
            h.update(v.detach().contiguous().numpy().tobytes())
    return h.hexdigest()[:16]


def run(
    name: str,
    pin: str,
    outside: dict,
    *,
    epochs: int,
    seed: int,
    out: Path,
    train: dict | None = None,
    variant: str = "calib",
    keys: tuple[str, ...] = ("own_error", "own_corr_anchored", "rollout"),
) -> dict:
    """The study's training rule for ``epochs`` (``variant``, seed ``seed``) under kernel pin ``pin`` with ``outside``
    set in the environment (and ``train`` overriding config ``model.train``), in a work folder of its own; the last
    epoch's validation ``keys``."""
    work = out / name.replace(" ", "_").replace(",", "")
    fresh_work_folder(work)
    import yaml

    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    config["kernels"] = {"pin": pin}
    config["model"]["seeds"] = [seed]
    config["model"]["train"]["epochs"] = epochs
    config["model"]["train"].update(train or {})
    (work / "config.yaml").write_text(yaml.safe_dump(config, sort_keys=False))
    target = f"results/model/{variant}/seed{seed}/training.json"
    env = {k: v for k, v in os.environ.items() if k not in environment("avx2")}
    env.update(outside)
    cmd = [
        "snakemake",
        "-s",
        str(ROOT / "Snakefile"),
        "-d",
        str(work),
        "--cores",
        "2",
        "--quiet",
        "all",
        "--allowed-rules",
        "model_train",
        "--",
        target,
    ]
    t0 = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, cwd=work)
    wall = time.perf_counter() - t0
    last = json.loads((work / target).read_text())["history"][-1]
    return {
        "name": name,
        "pin": pin,
        "wall_s": round(wall, 1),
        "weights": weights_digest(work / f"results/model/{variant}/seed{seed}/model.pt"),
        "validation": {k: last[k] for k in keys if k in last},
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--epochs", type=int, default=3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("/tmp/kernels"))
    args = ap.parse_args(argv)
    if missing_inputs():
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    rows = [run(n, p, o, epochs=args.epochs, seed=args.seed, out=args.out) for n, p, o in CONDITIONS]
    (args.out / "kernels.json").write_text(json.dumps(rows, indent=1))
    print("| condition | weights (sha256, first 16) | validation, last epoch | time (s) |")
    print("|---|---|---|---|")
    for r in rows:
        val = ", ".join(f"{k} {v:.6g}" for k, v in r["validation"].items() if isinstance(v, float | int))
        print(f"| {r['name']} | {r['weights']} | {val} | {r['wall_s']} |")
    by = {r["name"]: r for r in rows}
    native, pinned = by["native, this machine"], by["pinned, this machine"]
    print(f"\nwithout the pin the two machines agree: {native['weights'] == by['native, AVX2 machine']['weights']}")
    same = all(by[n]["weights"] == pinned["weights"] for n in by if n.startswith("pinned"))
    print(f"with the pin every condition agrees: {same}")
    print(f"time, pinned / native on this machine: {pinned['wall_s'] / native['wall_s']:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
