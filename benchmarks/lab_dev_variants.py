"""The lab benchmark's development set diagnosed under design variants: where the diagnostic's new parts are chosen.

The development set (config ``gap.lab_benchmark``, ``development_seed``; MuJoCo contact variants and Bullet, never
SAPIEN) is diagnosed by ``imply study gap diagnose-many`` in two shards (one process per core) once per variant, and each
variant is scored as the workflow scores the lab benchmark (:func:`imply.realworld.benchmark.score_contact_cases`),
over all logs and over the logs with probes. The variants:

- ``before``: the library without the contact's effects, no probes, the launch the table's (the diagnostic as it was);
- ``probes``: + the probes in every fit;
- ``contact``: + the box-table contact's effects (``table_timeconst``, ``table_dampratio``);
- ``launch``: + each push's launch left free;
- ``probes_contact``: probes and the contact's effects, the launch the table's (the default design);
- ``all``: probes, the contact's effects and the free launch.

Run: python benchmarks/lab_dev_variants.py --logs DIR --labels labels.json --table table.npz --cache-dir DIR
     --out /tmp/lab-dev [--variants before,probes,...]

Prints, per variant, the targets' metrics with counts, per engine; writes ``<out>/variants.json``. The told-the-cause
column is what a verdict rule could reach on those fits (the true effect's own hypothesis within tolerance).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import yaml
from gap_contact_dev import run_shards

from imply.diagnose.physics.candidates import CONTACT, get
from imply.realworld.benchmark import find_summaries, score_contact_cases
from imply.realworld.lab import LabBenchmarkConfig
from imply.realworld.lab_score import METRICS as LAB_METRICS

ROOT = Path(__file__).resolve().parents[1]
METRICS = tuple(key for key, *_ in LAB_METRICS)  # the lab score's metrics, in its order
WITHOUT_CONTACT = [c.name for c in get() if c.name not in CONTACT]
VARIANTS = {
    "before": ({"use_probes": False}, WITHOUT_CONTACT),
    "probes": ({"use_probes": True}, WITHOUT_CONTACT),
    "contact": ({"use_probes": False}, None),
    "launch": ({"use_probes": False, "free_launch": True}, WITHOUT_CONTACT),
    "probes_contact": ({"use_probes": True, "free_launch": False}, None),
    "all": ({"use_probes": True, "free_launch": True}, None),
}


def diagnose(variant: str, logs: list[Path], args, config: dict) -> Path:
    """Diagnose every log under a variant (two shards, one per core); returns the reports folder."""
    out = Path(args.out) / variant
    if (out / "done").is_file():
        return out
    changes, effects = VARIANTS[variant]
    opts = json.dumps({**config["diagnose"], **changes})
    grid = json.dumps(config["effect_grid"])
    cmds = []
    for k in range(2):
        shard = [str(p) for p in logs[k::2]]
        cmd = ["imply", "study", "gap", "diagnose-many", *shard, "--table", args.table, "--effect-grid-json", grid]
        cmd += ["--options-json", opts, "--cache-dir", args.cache_dir, "--threads", "1", "--no-plots"]
        cmd += ["-o", str(out / f"shard{k}")]
        if effects is not None:
            cmd += ["--effects", ",".join(effects)]
        cmds.append(cmd)
    if not run_shards(cmds):
        sys.exit(f"{variant}: diagnose-many failed")
    (out / "done").write_text("")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--logs", required=True, help="the development set's logs folder")
    ap.add_argument("--labels", required=True, help="its labels")
    ap.add_argument("--table", required=True)
    ap.add_argument("--cache-dir", required=True, help="effect tables of the whole library")
    ap.add_argument("--out", required=True)
    ap.add_argument("--variants", default=",".join(VARIANTS))
    args = ap.parse_args()
    config = yaml.safe_load((ROOT / "config.yaml").read_text())["gap"]
    design = LabBenchmarkConfig.from_dict(config["lab_benchmark"])
    labels = json.loads(Path(args.labels).read_text())
    logs = sorted(p for p in Path(args.logs).glob("*.csv") if not p.stem.endswith((".track", ".probes")))
    Path(args.out).mkdir(parents=True, exist_ok=True)
    probe_ids = sorted(c for c, lab in labels.items() if lab.get("probes"))
    result = {}
    for variant in args.variants.split(","):
        t0 = time.perf_counter()
        folder = diagnose(variant, logs, args, config)
        seconds = time.perf_counter() - t0
        found = find_summaries(labels, [folder / "shard0", folder / "shard1"])
        kw = dict(targets=design.targets, min_size_sd=design.min_size_sd)
        every = score_contact_cases(labels, found, **kw)
        probed = score_contact_cases({c: labels[c] for c in probe_ids}, {c: found[c] for c in probe_ids}, **kw)
        result[variant] = {"all": every, "probe_logs": probed, "seconds": seconds}
        print(f"\n{variant} ({seconds:.0f} s wall, median {every['seconds_per_log_median']:.1f} s a log)")
        for key in METRICS:
            cells = []
            for name, r in (("all", every), ("probe logs", probed)):
                x, n = r.get(key), r.get(f"n_{key}")
                per = ", ".join(
                    f"{e} {r[f'{key}_{e}']:.2f}/{r[f'n_{key}_{e}']}"
                    for e in ("mujoco", "bullet")
                    if r.get(f"n_{key}_{e}")
                )
                cells.append(f"{name} {x:.2f} (n {n}; {per})" if n is not None else f"{name} {x:.2f}")
            print(f"  {key:20s} " + " | ".join(cells))
    (Path(args.out) / "variants.json").write_text(json.dumps(result, indent=1, default=str))


if __name__ == "__main__":
    main()
