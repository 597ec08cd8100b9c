"""Is the no-calibration model worse than the object-blind baseline, or only noisier? A paired bootstrap.

Reads the per-object Section 5 scores of a finished run (``results/section5/per_object.csv``)
and, for each data-order seed, prints the no-calibration model's mean log error, the
object-blind baseline's on the same objects, their difference, and the difference's
95% interval from resampling the objects (pairs kept together)::

    python benchmarks/s5_blind_gap.py
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
import pandas as pd


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--per-object", default="results/section5/per_object.csv")
    ap.add_argument("--draws", type=int, default=2000)
    ap.add_argument("--seed", type=int, default=0, help="resampling seed")
    args = ap.parse_args(argv)
    scores = pd.read_csv(args.per_object, dtype={"object_id": str})
    rng = np.random.default_rng(args.seed)
    print(f"{'seed':>4} {'model':>7} {'baseline':>9} {'difference':>11} {'95% interval':>18}")
    for seed, f in scores.groupby("seed"):
        model = f[f["model"] == "nocalib"].set_index("object_id")["log_error"]
        blind = f[f["model"] == "blind_nocalib_objects"].set_index("object_id")["log_error"].loc[model.index]
        diff = (model - blind).to_numpy()
        draws = rng.choice(diff, size=(args.draws, diff.size)).mean(axis=1)
        lo, hi = np.percentile(draws, [2.5, 97.5])
        print(f"{seed:>4} {model.mean():7.3f} {blind.mean():9.3f} {diff.mean():11.4f}   [{lo:+.4f}, {hi:+.4f}]")
    return 0


if __name__ == "__main__":
    sys.exit(main())
