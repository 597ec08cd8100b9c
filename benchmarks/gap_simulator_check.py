"""What the simulator check did to a benchmark set's verdicts: the causes the tables would state, those the simulator
or the probes withdrew, each against the set's truth, and the re-simulated share of the gap beside the predicted one.

Reads a folder of reports (one folder per log, each with ``summary.json``, as ``imply study gap diagnose-many`` writes
them) and the set's ``labels.json`` (what each log's world injected). A cause is *right* where the log's world
injected that library effect (its tilt components read as ``tilt``), *wrong* otherwise (every cause of a null log).

Run: python benchmarks/gap_simulator_check.py results/gap/development/contact/reports \
         results/gap/development/contact/labels.json [--cases]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pandas as pd

from imply.diagnose.conclusion.simulator_check import compare_shares

TILT_PARTS = {"tilt_x": "tilt", "tilt_y": "tilt"}
CONTACT = {"table_timeconst", "table_dampratio"}


def truth_of(label: dict) -> set[str]:
    """The library effects a log's world injected, by the diagnostic's candidate names, with the changes of the
    table contact's MJCF parameters its contact model made (``table_timeconst``, ``table_dampratio``)."""
    effects = {TILT_PARTS.get(e["name"], e["name"]) for e in label.get("effects", []) if e.get("in_library", True)}
    contact = set((label.get("contact") or {}).get("parameters", {})) & CONTACT
    return effects | contact


def rows(reports: Path, labels: dict) -> pd.DataFrame:
    out = []
    # a folder of report folders, or of shards of them (the workflow diagnoses in shards)
    folders = sorted(p.parent for p in reports.rglob("summary.json"))
    for folder in folders:
        s = json.loads((folder / "summary.json").read_text())
        label = labels.get(folder.name)
        if label is None:
            continue
        truth = truth_of(label)
        v, c = s["verdict"], s.get("simulator")
        tables = list(v["effects"]) + list(v.get("withdrawn", []))
        # judged again from the stored shares, so that reports written under an earlier rule read as this code would
        by = []
        if c is not None:
            if compare_shares(c["share_closed"], c["predicted_share_closed"], c["tolerance"])[1]:
                by.append("simulator")
            if c["probes_contradict"]:
                by.append("probes")
        stated = [] if by else tables
        out.append(
            {
                "log": folder.name,
                "group": label["group"],
                "truth": "+".join(sorted(truth)) or "none",
                "tables_state": "+".join(tables) or "none",
                "stated": "+".join(stated) or "none",
                "withdrawn_by": "+".join(by),
                "tables_right": sum(e in truth for e in tables),
                "tables_wrong": sum(e not in truth for e in tables),
                "stated_right": sum(e in truth for e in stated),
                "stated_wrong": sum(e not in truth for e in stated),
                "checked": c is not None,
                "share_resimulated": c["share_closed"] if c else np.nan,
                "share_predicted": c["predicted_share_closed"] if c else np.nan,
                "disagrees": bool(c["disagrees"]) if c else False,
                "tolerance": c["tolerance"] if c else np.nan,
                "before_resimulated": c["before_rms"] if c else np.nan,
                "after_resimulated": c["after_rms"] if c else np.nan,
                "before_predicted": c["predicted_before_rms"] if c else np.nan,
                "after_predicted": c["predicted_after_rms"] if c else np.nan,
                "probes_worst_p": min((k["p_value"] for k in c["probes"]), default=np.nan) if c else np.nan,
                "seconds": c["seconds"] if c else 0.0,
            }
        )
    return pd.DataFrame(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("reports", type=Path, help="folder of report folders (one per log; in shard folders or not)")
    ap.add_argument("labels", type=Path, help="the set's labels.json")
    ap.add_argument("--cases", action="store_true", help="print every log whose verdict states or withdrew a cause")
    args = ap.parse_args()
    frame = rows(args.reports, json.loads(args.labels.read_text()))
    if frame.empty:
        raise SystemExit(f"no report with a label in {args.reports}")
    checked = frame[frame["checked"]]
    diff = (checked["share_resimulated"] - checked["share_predicted"]).abs().dropna()
    print(f"{len(frame)} logs; {len(checked)} with causes the tables stated, put into the simulator")
    print(
        f"causes the tables stated: {frame['tables_right'].sum()} right, {frame['tables_wrong'].sum()} wrong; "
        f"after the check: {frame['stated_right'].sum()} right, {frame['stated_wrong'].sum()} wrong"
    )
    for who in ("simulator", "probes"):
        hit = frame["withdrawn_by"].str.contains(who)
        print(
            f"withdrawn by the {who}: {int(hit.sum())} logs "
            f"({int(frame.loc[hit, 'tables_right'].sum())} right causes, {int(frame.loc[hit, 'tables_wrong'].sum())} wrong)"
        )
    if len(diff):
        print(
            f"re-simulated against predicted share: median |difference| {diff.median():.3f}, largest {diff.max():.3f}, "
            f"beyond the tolerance in {int(checked['disagrees'].sum())} of {len(checked)}"
        )
        short = checked["share_predicted"] - checked["share_resimulated"]
        # where the two disagree beyond the tables' tolerance (a gap barely above the noise makes shares swing)
        for kind, rows_ in (("right", checked["tables_wrong"] == 0), ("wrong", checked["tables_wrong"] > 0)):
            rows_ = rows_ & checked["disagrees"]
            if rows_.any():
                print(
                    f"largest shortfall (predicted - re-simulated share) where they disagree, logs whose causes are "
                    f"all {kind}: {short[rows_].max():.3f} over {int(rows_.sum())} logs"
                )
        print(
            f"seconds per checked log: median {checked['seconds'].median():.1f}, largest {checked['seconds'].max():.1f}"
        )
    if args.cases:
        show = frame[(frame["tables_state"] != "none")]
        with pd.option_context("display.width", 200, "display.max_rows", 500):
            print(show.drop(columns=["checked"]).to_string(index=False, float_format=lambda x: f"{x:.3g}"))


if __name__ == "__main__":
    main()
