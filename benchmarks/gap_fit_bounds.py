"""The diagnosis's joint fits with a box held at its bound against the same fits with its step clipped there.

Diagnoses push logs in one process (``imply study gap diagnose-many``, the workflow's settings from config.yaml)
and, at every joint fit the diagnosis makes (:meth:`imply.diagnose.inference.fit.Problem.fit`), fits the same
model from the same start twice: as the code does (a box's parameter at its bound that the pushes pull past it
held there for the step) and with that hold taken out (the step clipped at the bound, as before the hold). The
diagnosis goes on with the held fit. Prints how many fits of each kind stop at the step limit, how their
objectives (sum of squares plus the discrepancy's prior) compare, and each kind's CPU time.

Run: python benchmarks/gap_fit_bounds.py LOG.csv ... [--cache-dir results/gap/effect_tables]
Needs the push table and the gap stage's effect tables (snakemake --cores 2 results/gap/effect_tables).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time

import numpy as np
import yaml
from baseline_tree import ROOT

import imply.diagnose.inference.fit as fit_module
from imply.cli import main as imply_main


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("logs", nargs="+", help="push logs to diagnose")
    ap.add_argument("--table", default=str(ROOT / "results/table/table.npz"))
    ap.add_argument("--cache-dir", default=str(ROOT / "results/gap/effect_tables"))
    args = ap.parse_args()
    config = yaml.safe_load((ROOT / "config.yaml").read_text())["gap"]

    held_fit = fit_module.Problem.fit
    hold = fit_module.Problem._hold_at_bounds
    rows = []  # (iterations, objective, CPU s) of the held fit, then of the clipped one

    def both(self, model, theta0, start, iters=25, tol=1e-8):
        out = []
        for holding in (True, False):
            fit_module.Problem._hold_at_bounds = hold if holding else (lambda self, objs, A, B, g_u: (A, B, g_u))
            t0 = time.process_time()
            result = held_fit(self, model, theta0, start, iters=iters, tol=tol)
            seconds = time.process_time() - t0
            objective = result.sse + float(model.prior_precision() @ result.theta**2)
            out.append((result, result.iterations, objective, seconds))
        fit_module.Problem._hold_at_bounds = hold
        rows.append([value for _, *values in out for value in values])
        return out[0][0]

    fit_module.Problem.fit = both
    with tempfile.TemporaryDirectory() as out:
        imply_main(
            ["study", "gap", "diagnose-many", *args.logs, "--table", args.table, "--cache-dir", args.cache_dir]
            + [
                "--effect-grid-json",
                json.dumps(config["effect_grid"]),
                "--options-json",
                json.dumps(config["diagnose"]),
            ]
            + ["--threads", "1", "--no-plots", "-o", out]
        )
    fit_module.Problem.fit = held_fit

    a = np.array(rows)
    limit = 25
    gain = a[:, 4] - a[:, 1]  # the clipped objective less the held one: > 0 where holding ends lower
    print(f"{len(args.logs)} logs, {len(a)} joint fits")
    print(
        f"fits at the {limit}-step limit: held {int((a[:, 0] >= limit).sum())}, clipped {int((a[:, 3] >= limit).sum())}"
    )
    print(
        f"held ends lower by > 0.01: {int((gain > 0.01).sum())} (by up to {gain.max():.2f}); higher by > 0.01: "
        f"{int((gain < -0.01).sum())} (by up to {max(-gain.min(), 0.0):.2f})"
    )
    print(
        f"CPU of the fits: held {a[:, 2].sum():.1f} s, clipped {a[:, 5].sum():.1f} s, ratio {a[:, 2].sum() / a[:, 5].sum():.2f}"
    )


if __name__ == "__main__":
    main()
