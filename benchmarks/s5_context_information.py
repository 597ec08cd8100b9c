"""How much does each query frame reveal the object? The check behind the query context of Section 5.

A model trained without calibration is meant to be object-blind: its context (the
query's first frames) should not tell one object from another. This fits a ridge
regression from the real encoder tokens of chosen query frames (pooled as the
predictor sees them) and the push's log speed to the object's part of the log slide
(log slide minus the training set's typical log slide at that speed) on the training
clips, and reports on the held-out objects its correlation with the truth (per push
and per object, averaged over its five speeds) and its mean absolute error beside the
object-blind baseline's. Frames that give r near 0 are object-blind; frames with a
large r already show the box sliding, and a model with them in context can track the
object without any calibration push::

    python benchmarks/s5_context_information.py            # after snakemake has built results/features
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import torch
import yaml
from sklearn.linear_model import RidgeCV

from imply.models.ac_predictor import normalise_tokens
from imply.models.features import load_feature_split
from imply.models.object_blind import typical_slide_of_clips


def _design(split, frames, typical):
    meta = split.meta
    q = ((meta["role"] == "query") & (meta["displacement"] > 0)).to_numpy()
    tokens = normalise_tokens(torch.from_numpy(split.tokens[q][:, frames].astype(np.float32))).numpy()
    speed = meta["speed"].to_numpy()[q]
    y = np.log(meta["displacement"].to_numpy()[q]) - typical.log_slide(speed)
    return np.c_[tokens.reshape(q.sum(), -1), np.log(speed)], y, meta["object_id"].to_numpy()[q]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--results", default="results")
    ap.add_argument("--config", default="config.yaml")
    args = ap.parse_args(argv)
    res = Path(args.results)
    grid = yaml.safe_load(Path(args.config).read_text())["model"].get("token_grid")
    grid = tuple(grid) if grid else None
    train = load_feature_split(res / "features/train.npz", res / "clips/train.csv").pooled(grid)
    held = load_feature_split(res / "features/heldout_nocalib.npz", res / "clips/heldout_nocalib.csv").pooled(grid)
    typical = typical_slide_of_clips(train.meta)
    print(f"{'query frames':>14} {'r (push)':>9} {'r (object)':>11} {'|error|':>8} {'blind |error|':>14}")
    for frames in ([0], [1], [0, 1], [0, 1, 2]):
        x, y, _ = _design(train, frames, typical)
        xt, yt, ids = _design(held, frames, typical)
        pred = RidgeCV(alphas=np.logspace(-2, 5, 15)).fit(x, y).predict(xt)
        per_object = pd.DataFrame({"o": ids, "p": pred, "y": yt}).groupby("o").mean()
        print(
            f"{str(frames):>14} {np.corrcoef(pred, yt)[0, 1]:9.2f} {np.corrcoef(per_object.p, per_object.y)[0, 1]:11.2f}"
            f" {np.mean(np.abs(pred - yt)):8.3f} {np.mean(np.abs(yt)):14.3f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
