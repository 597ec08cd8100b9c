"""A diagnosis against a reference session, timed against the same log's diagnosis alone, in one process.

Takes the first ``--logs`` logs of a lab set (``results/gap/lab/<set>/logs``, with their reference sessions in
``references/``), and diagnoses each alone (its probes used, as the lab's probes tier) and against its reference,
alternating the order over ``--repeats`` rounds, with the workflow's settings (config.yaml ``gap``). Prints each
log's seconds both ways, the medians and their ratio (the target: at most 2).

Run: python benchmarks/diagnose_reference_time.py [--set development] [--logs 8] [--repeats 2]
Needs the set's logs and references, the push table and the effect tables
(snakemake --cores 2 results/gap/lab/development/score.json).
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import yaml

from imply.diagnose.analysis import DiagnosisConfig
from imply.diagnose.physics.candidates import get
from imply.diagnose.physics.effect_tables import CoarseGrid
from imply.diagnose.run import DiagnoseRequest, Report, diagnose_report, prepare, read_checked_pushlog
from imply.table import PushTable

ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", default="development", choices=("development", "sealed"))
    ap.add_argument("--logs", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=2)
    args = ap.parse_args()
    config = yaml.safe_load((ROOT / "config.yaml").read_text())
    gap = config["gap"]
    folder = ROOT / "results/gap/lab" / args.set
    logs = sorted(p for p in (folder / "logs").glob("*.csv") if "." not in p.stem)[: args.logs]
    table = PushTable.load(ROOT / "results/table/table.npz")
    options = DiagnosisConfig.from_dict({**gap["diagnose"], "use_probes": True}, "gap.diagnose")
    candidates = tuple(get(gap["candidates"]) if gap.get("candidates") else get())
    request = DiagnoseRequest(
        table=table,
        candidates=candidates,
        options=options,
        grid=CoarseGrid.from_dict(gap["effect_grid"], "gap.effect_grid"),
        cache_dir=ROOT / "results/gap/effect_tables",
        plots=False,
    )
    session = prepare(request, progress=False)
    times: dict[str, list[float]] = {"alone": [], "reference": []}
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.repeats):
            for path in logs:
                log = read_checked_pushlog(path, table)
                ref = read_checked_pushlog(folder / "references" / path.name, table)
                order = ("alone", "reference") if r % 2 == 0 else ("reference", "alone")
                for how in order:
                    report = Report(
                        pushlog=log,
                        folder=Path(tmp) / f"{path.stem}-{how}",
                        reference=ref if how == "reference" else None,
                    )
                    t0 = time.perf_counter()
                    diagnose_report(report, session, force=True)
                    times[how].append(time.perf_counter() - t0)
                print(
                    f"round {r} {path.stem}: alone {times['alone'][-1]:.2f} s, with reference {times['reference'][-1]:.2f} s"
                )
    alone, ref = statistics.median(times["alone"]), statistics.median(times["reference"])
    print(f"median over {len(times['alone'])} diagnoses: alone {alone:.2f} s, with a reference {ref:.2f} s")
    print(f"ratio (with a reference / alone): {ref / alone:.2f}")


if __name__ == "__main__":
    main()
