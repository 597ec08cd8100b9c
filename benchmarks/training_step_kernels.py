"""What the kernel pin costs a Section 5 training step: milliseconds per step under each pinned variable.

Times ``--steps`` training steps of the calibrated predictor (the config's tiny preset, batch
``model.train.batch_size``, one torch thread) on the cached training features, once per environment: the
machine's own kernels, each variable of ``imply.kernels.environment("avx2")`` alone, and the whole pin. Each runs
in a fresh process (the variables are read when the libraries load), in the same run, and prints its median
over ``--repeats`` rounds and its ratio to the machine's own kernels. With ``--pairs`` every setting also runs
as two processes side by side, as the study runs its trainings.

Run: python benchmarks/training_step_kernels.py [--steps 30] [--repeats 2] [--pairs]
Needs the cached features (snakemake --cores 2 results/features/train.npz results/clips/train.csv).
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]

STEPS = """
import json, sys, time
import numpy as np, torch
from imply.models.ac_predictor import ACPredictor
from imply.models.config import Layout, PredictorPreset, TrainConfig
from imply.models.examples import training_objects, training_sequences
from imply.models.features import load_feature_split
from imply.models.train import losses

cfg = json.loads(sys.argv[1])
torch.set_num_threads(1)
torch.use_deterministic_algorithms(True, warn_only=True)
split = load_feature_split(cfg["features"], cfg["clips"]).pooled(tuple(cfg["token_grid"]))
layout = Layout.from_dict({**cfg["variant"], "rest_state": cfg["rest_state"]})
seqs = training_sequences(split, layout, training_objects(split))
preset = PredictorPreset.from_dict(cfg["preset"])
model = ACPredictor(preset.predictor(embed_dim=int(split.tokens.shape[-1]), grid=split.grid, max_steps=layout.n_steps))
train = TrainConfig.from_dict(cfg["train"])
opt = torch.optim.AdamW(model.parameters(), lr=train.lr)
bs = train.batch_size
tf_weights = torch.as_tensor(
    layout.teacher_forcing_weights(final_weight=train.final_weight, calib_targets=train.calib_targets),
    dtype=torch.float32,
)

def step(i):
    frames, actions, states = seqs.batch(np.arange(i * bs, (i + 1) * bs) % len(seqs))
    tf, ar = losses(model, frames, actions, states, n_context=seqs.n_context, tf_weights=tf_weights, cfg=train)
    opt.zero_grad(set_to_none=True)
    (tf + train.rollout_weight * ar).backward()
    torch.nn.utils.clip_grad_norm_(model.parameters(), train.grad_clip)
    opt.step()

for i in range(5):  # warm-up
    step(i)
t0 = time.perf_counter()
for i in range(cfg["steps"]):
    step(i)
print(json.dumps({"ms": 1000 * (time.perf_counter() - t0) / cfg["steps"]}))
"""


def settings() -> dict[str, dict[str, str]]:
    """The environments compared: none, each pinned variable alone, the whole pin."""
    from imply.kernels import environment

    pin = environment("avx2")
    return {"own kernels": {}, **{f"{k}={v}": {k: v} for k, v in pin.items()}, "whole pin": pin}


def run(cfg: dict, env: dict[str, str], side_by_side: int) -> list[float]:
    """Milliseconds per step of ``side_by_side`` processes started together under ``env``."""
    base = {k: v for k, v in os.environ.items() if k not in settings()["whole pin"]}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", STEPS, json.dumps(cfg)],
            env={**base, **env},
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
            text=True,
        )
        for _ in range(side_by_side)
    ]
    return [json.loads(p.communicate()[0].strip().splitlines()[-1])["ms"] for p in procs]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--steps", type=int, default=30)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--pairs", action="store_true", help="also two processes side by side per setting")
    args = ap.parse_args()
    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    model = config["model"]
    cfg = {
        "features": str(ROOT / "results/features/train.npz"),
        "clips": str(ROOT / "results/clips/train.csv"),
        "token_grid": model["token_grid"],
        "variant": model["variants"]["calib"],
        "rest_state": model["rest_state"],
        "preset": model["presets"][model["preset"]],
        "train": model["train"],
        "steps": args.steps,
    }
    medians: dict[str, float] = {}
    for name, env in settings().items():
        alone = [run(cfg, env, 1)[0] for _ in range(args.repeats)]
        medians[name] = statistics.median(alone)
        line = f"{name:45s} alone {medians[name]:6.1f} ms/step  ratio {medians[name] / medians['own kernels']:.2f}"
        if args.pairs:
            pair = [ms for _ in range(args.repeats) for ms in run(cfg, env, 2)]
            line += f"  side by side {statistics.median(pair):6.1f} ms/step"
        print(line, flush=True)


if __name__ == "__main__":
    main()
