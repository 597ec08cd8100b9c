"""Section 5 ablation: train the predictor under one recipe and score it on the VALIDATION objects only.

Runs one data-order seed of the calibrated and the context-free model on the cached
features of a finished ``snakemake`` run (results/features, results/clips, results/table)
and prints one line: every Table 3 quantity per context on the validation split
(``clips.n_validation`` objects in no training or held-out set), read by the real-clip
readout (results/model/readout_ln.npz, fitted on the training clips' real rest frames),
the own-vs-swap shares, the object-blind baseline's error, and the seconds per model.
The held-out objects are never touched: recipes are chosen here, and the held-out
objects are scored once, by the workflow, with the final recipe.

``--own-readout`` adds the ablation line the study no longer uses: the same rollouts read
by a readout fitted on the model's own rollouts of its training objects (an instrument
the model shaped, so it is never used to measure).

Each recipe is the config's ``model`` section with ``--set`` overrides, so a line of the
ablation table of docs/notes/section5-recipe.md is one command::

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
from imply.models.examples import training_objects, training_sequences
from imply.models.features import load_feature_split
from imply.models.latent_readout import fit_rollout_readout, load_latent_readout
from imply.models.object_blind import typical_slide_of_clips
from imply.models.train import load_model, train_variant
from imply.score import ScoreConfig
from imply.study.section5.validation import validation_scores
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
    ap.add_argument("--own-readout", action="store_true", help="also read with the model's own-rollout readout")
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
    val = load_feature_split(res / "features/validation.npz", res / "clips/validation.csv").pooled(grid)
    readout = load_latent_readout(res / "model/readout_ln.npz")
    preset = PredictorPreset.from_dict(model_cfg["presets"][model_cfg["preset"]])
    scorer = ScoreConfig.from_dict(config["score"]).scorer(PushTable.load(res / "table/table.npz"))
    typical = typical_slide_of_clips(train.meta)
    line: dict = {"name": args.name, "set": args.set, "seed": args.seed, "scored_on": "validation"}
    for variant in args.models.split(","):
        layout = Layout.from_dict({**model_cfg["variants"][variant], "rest_state": model_cfg["rest_state"]})
        t0 = time.perf_counter()
        with tempfile.TemporaryDirectory() as tmp:
            train_variant(
                train,
                preset=preset,
                layout=layout,
                config=TrainConfig.from_dict(model_cfg["train"]),
                data_seed=args.seed,
                out=Path(tmp) / "m.pt",
                checkpoint=Path(tmp) / "c.pt",
            )
            model, _, _ = load_model(Path(tmp) / "m.pt")
        line[f"{variant}_seconds"] = round(time.perf_counter() - t0, 1)
        readers = {"real": readout}
        if args.own_readout:
            objects = training_objects(train)
            slides = train.meta["displacement"].to_numpy(dtype=float)[objects.query]
            readers["own"] = fit_rollout_readout(model, training_sequences(train, layout, objects), slides)
        for name, reader in readers.items():
            scores = validation_scores(
                model,
                layout,
                val,
                readout=reader,
                scorer=scorer,
                typical=typical,
                derangement_seed=model_cfg["derangement_seed"],
            )
            key = variant if name == "real" else f"{variant}_own_readout"
            line[key] = {k: round(v, 3) for k, v in scores.items()}
    print(json.dumps(line), flush=True)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    with out.open("a") as fh:
        fh.write(json.dumps(line) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
