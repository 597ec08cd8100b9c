"""The world's error on stiff table contacts: its steps shortened by the contact's time constant, against not.

Draws pushes from the other-contact benchmark's development set (its MuJoCo world's logs, effects and contact
variants included, through :func:`imply.realworld.cases.accuracy_sample`), keeps those whose box-table contact is
stiffer than the scene's (``table_timeconst`` below 1) and as many others, and simulates each with the world's
stepping twice, with ``contact_steps`` on (the default) and off, against the same pushes four times finer with it
on. Prints, per group and setting, the largest and RMS log-d difference, how many pushes differ by more than the
table's own measured error (the world's design rule: ``numerical_error`` in the metadata of ``--table``, the
workflow's ``results/table/table.npz``), the mean steps and the CPU time against the default's, in one process.

Usage: ``python benchmarks/world_stiff_contacts.py --draw 240 --table results/table/table.npz``
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np
import yaml

from imply.realworld.cases import ContactBenchmarkConfig, accuracy_sample, draw_cases
from imply.realworld.world import simulate_world
from imply.sim.scene import SceneConfig
from imply.table import PushTable

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=ROOT / "config.yaml")
    ap.add_argument("--draw", type=int, default=240, help="pushes drawn from the development set's logs")
    ap.add_argument("--seed", type=int, default=5, help="the draw's seed (beside the set's own)")
    ap.add_argument("--table", type=Path, default=ROOT / "results" / "table" / "table.npz", help="the push table")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args(argv)
    rule = (PushTable.load(args.table).meta.get("numerical_error") or {}).get("max_abs_log_d")
    if rule is None:
        print(f"{args.table} records no measured numerical error (the table rule's check)", file=sys.stderr)
        return 2
    cfg = yaml.safe_load(args.config.read_text())
    section = dict(cfg["gap"]["contact_benchmark"])
    section["seed"] = section["development_seed"]
    design = ContactBenchmarkConfig.from_dict(section)
    scene = SceneConfig.from_dict(cfg["scene"])
    cases = [c for c in draw_cases(design) if c.get("engine", "mujoco") == "mujoco"]
    sample, _ = accuracy_sample(cases, design, scene, args.draw, 1, seed=args.seed)
    stiff = np.flatnonzero(sample.params["table_timeconst"] < 1.0)
    others = np.flatnonzero(sample.params["table_timeconst"] >= 1.0)[: stiff.size]
    on = design.stepping
    off = dataclasses.replace(on, contact_steps=False)
    print(f"{sample.n} pushes drawn from the development set (seed {design.seed}); {stiff.size} stiff; rule {rule:.4f}")
    print("| pushes | stepping | max log d diff | RMS | beyond the rule | mean steps | CPU vs default |")
    print("|---|---|---|---|---|---|---|")
    for group, idx in (("stiff", stiff), ("others", others)):
        pushes = sample.subset(idx)
        finer = simulate_world(pushes, scene, on.finer(4), nthread=args.threads, progress=False)
        cpu = {}
        for name, stepping in (("default (shortened)", on), ("nominal steps", off)):
            t0 = time.process_time()
            run = simulate_world(pushes, scene, stepping, nthread=args.threads, progress=False)
            cpu[name] = time.process_time() - t0
            ok = run.ok & finer.ok
            diff = np.log(run.displacement[ok]) - np.log(finer.displacement[ok])
            print(
                f"| {group} ({ok.sum()}) | {name} | {np.abs(diff).max():.4f} | {np.sqrt(np.mean(diff**2)):.4f} | "
                f"{int((np.abs(diff) > rule).sum())} | {run.steps.mean():.0f} | "
                f"{cpu[name] / cpu['default (shortened)']:.2f} |"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
