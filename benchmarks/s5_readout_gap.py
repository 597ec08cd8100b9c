"""How far do a trained predictor's rest-frame tokens sit from real ones, and what does each readout make of them?

For one trained model (``results/model/<variant>/seed<k>/model.pt``) this rolls out its
training objects from their context, as evaluation does, and compares the predicted
rest-frame tokens with the real ones: their mean distance, and their spread across
objects. It then reads the predictions with the real-token readout
(``results/model/readout_ln.npz``) and with the model's own readout (``readout.npz``
beside the model) and prints each one's mean log bias, mean |log error|, and the
spread of its reading around the typical slide for the speed, beside the object-blind
baseline's error. The objects are the whole training split: the model was trained, and its own
readout fit, on all of them but the validation slice, so these numbers are nearly
in-sample; Table 3 gives the held-out ones::

    python benchmarks/s5_readout_gap.py --model results/model/nocalib/seed0/model.pt
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import torch

from imply.models.examples import training_objects, training_sequences
from imply.models.features import load_feature_split
from imply.models.latent_readout import load_latent_readout, real_last_tokens
from imply.models.object_blind import typical_slide_of_clips
from imply.models.rollout import final_tokens
from imply.models.train import load_model


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", required=True)
    ap.add_argument("--results", default="results")
    ap.add_argument("--threads", type=int, default=2)
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    res = Path(args.results)
    model, layout, payload = load_model(args.model)
    grid = payload.get("token_grid")
    split = load_feature_split(res / "features/train.npz", res / "clips/train.csv").pooled(
        tuple(grid) if grid else None
    )
    objects = training_objects(split)
    predicted = final_tokens(model, training_sequences(split, layout, objects), batch_size=200)
    real = real_last_tokens(split, objects.query)
    speed = split.meta["speed"].to_numpy(dtype=float)[objects.query]
    truth = np.log(split.meta["displacement"].to_numpy(dtype=float)[objects.query])
    typical = typical_slide_of_clips(split.meta).log_slide(speed)
    print(
        f"{len(truth)} training objects, {layout.n_steps}-step sequences ({'with' if layout.calib else 'no'} calibration)"
    )
    print(
        f"rest-frame tokens: mean |predicted - real| {np.mean(np.abs(predicted - real)):.4f}; spread across objects "
        f"{predicted.std(axis=0).mean():.4f} predicted vs {real.std(axis=0).mean():.4f} real"
    )
    print(f"object-blind baseline: mean |log error| {np.mean(np.abs(typical - truth)):.3f}")
    readouts = {
        "real-token readout": res / "model/readout_ln.npz",
        "model's own readout": Path(args.model).parent / "readout.npz",
    }
    for name, path in readouts.items():
        if not path.exists():
            print(f"{name}: {path} not found")
            continue
        read = load_latent_readout(path).predict_log(predicted)
        object_part = read - typical
        print(
            f"{name}: bias {np.mean(read - truth):+.3f}, mean |log error| {np.mean(np.abs(read - truth)):.3f}, "
            f"spread around the typical slide {object_part.std():.3f} (r with the truth's "
            f"{np.corrcoef(object_part, truth - typical)[0, 1]:.2f})"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
