"""Section 5 ablation: train the predictor under one recipe and score it on the held-out objects.

Runs one data-order seed of the calibrated and the context-free model on the cached
features of a finished ``snakemake`` run (results/features, results/clips,
results/table) and prints one line: tracking r and log error per context, the share of
objects whose anchored / self disagreement prefers their own calibration, the
object-blind baseline's error, and the seconds per model. Each recipe is the config's
``model`` section with ``--set`` overrides, so a line of the README's ablation table is
one command::

    python benchmarks/s5_ablation.py --name "final weight 1" --set train.final_weight=1.0

Lines are appended to ``--out`` (JSON lines) as well as printed.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import torch
import yaml

from imply.models.config import Layout, PredictorPreset, TrainConfig
from imply.models.features import load_feature_split
from imply.models.latent_readout import fit_latent_readout, load_latent_readout
from imply.models.object_blind import typical_slide_of_clips
from imply.models.rollout import rollout_split
from imply.models.train import load_model, train_variant
from imply.score import ScoreConfig
from imply.study.section5.rollouts import object_blind_rollouts, rollouts_by_context
from imply.study.section5.scoring import context_scores, own_lt_swap, score_context
from imply.table import PushTable


def _set(cfg: dict, assignment: str) -> None:
    key, _, text = assignment.partition("=")
    node = cfg
    *parents, leaf = key.split(".")
    for p in parents:
        node = node[p]
    node[leaf] = yaml.safe_load(text)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--name", required=True)
    ap.add_argument("--config", default="config.yaml")
    ap.add_argument("--results", default="results")
    ap.add_argument("--set", action="append", default=[], help="override in config.model, e.g. train.epochs=10")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--models", default="calib,nocalib")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--out", default="results/benchmarks/s5_ablation.jsonl")
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    config = yaml.safe_load(Path(args.config).read_text())
    model_cfg = config["model"]
    for a in args.set:
        _set(model_cfg, a)
    res = Path(args.results)
    grid = tuple(model_cfg["token_grid"]) if model_cfg.get("token_grid") else None
    train = load_feature_split(res / "features/train.npz", res / "clips/train.csv").pooled(grid)
    readout = fit_latent_readout(train)
    preset = PredictorPreset.from_dict(model_cfg["presets"][model_cfg["preset"]])
    scorer = ScoreConfig.from_dict(config["score"]).scorer(PushTable.load(res / "table/table.npz"))
    typical = typical_slide_of_clips(train.meta)
    line: dict = {"name": args.name, "set": args.set, "seed": args.seed}
    for variant in args.models.split(","):
        layout = Layout.from_dict({**model_cfg["variants"][variant], "rest_state": model_cfg["rest_state"]})
        split_name = "heldout_calib" if layout.calib else "heldout_nocalib"
        held = load_feature_split(res / f"features/{split_name}.npz", res / f"clips/{split_name}.csv").pooled(grid)
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            payload = train_variant(
                train, preset=preset, layout=layout, config=TrainConfig.from_dict(model_cfg["train"]),
                data_seed=args.seed, out=Path(tmp) / "m.pt",
                checkpoint=Path(tmp) / "c.pt", readout=readout, rollout_readout=Path(tmp) / "r.npz",
            )  # fmt: skip
            reader = load_latent_readout(Path(tmp) / "r.npz") if model_cfg["readout"] == "rollouts" else readout
            model, _, _ = load_model(Path(tmp) / "m.pt")
        line[f"{variant}_seconds"] = round(time.perf_counter() - t0, 1)
        line[f"{variant}_history"] = payload["history"][-1]
        line["readout"] = model_cfg["readout"]
        contexts = ("own", "swap", "none") if layout.calib else ("none",)
        table = rollout_split(
            model, layout, held, readout=reader, contexts=contexts,
            derangement_seed=model_cfg["derangement_seed"],
        )  # fmt: skip
        rollouts = rollouts_by_context(table)
        scored = {ctx: score_context(r, scorer) for ctx, r in rollouts.items()}
        for ctx, f in scored.items():
            s = context_scores(f)
            line[f"{variant}_{ctx}"] = {
                "track": round(s.track, 3), "error": round(s.error, 3),
                "self": round(s.self_disagreement, 3), "anchored": round(s.anchored_disagreement, 3),
            }  # fmt: skip
        if layout.calib:
            prefers_own = own_lt_swap(scored["own"], scored["swap"])
            line["own_lt_swap"] = {"self": prefers_own.self_disagreement, "anchored": prefers_own.anchored_disagreement}
            blind = context_scores(score_context(object_blind_rollouts(rollouts["own"], typical), scorer))
            line["blind_error"] = round(blind.error, 3)
    print(json.dumps(line), flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("a") as fh:
        fh.write(json.dumps(line) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
