"""A development run's verdicts judged again, stating causes wherever the gap is at least partly explained.

Reads the summaries that ``benchmarks/gap_contact_dev.py`` wrote for a run (``--out``, ``--name``),
judges each log's hypothesis table again with :func:`imply.diagnose.conclusion.verdict.judge` as if its gap were
explained wherever it is partly explained (adequacy and identification fully separate; the adequacy
itself is kept), and scores both readings of the same fits with
:func:`imply.realworld.benchmark.score_contact_cases`. Nothing is diagnosed again.

Run: python benchmarks/gap_rejudge.py --out /tmp/cdev-t --name final
     python benchmarks/gap_rejudge.py --labels labels.json --reports DIR [DIR ...] [--probe-logs-only]
       (any benchmark's labels and report folders, e.g. the lab development set's; with --probe-logs-only the
       causes are stated only where the log's probes entered its fits)
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import yaml

from imply.diagnose.analysis import Summary
from imply.diagnose.conclusion.verdict import Adequacy, judge
from imply.realworld.benchmark import find_summaries, score_contact_cases

ROOT = Path(__file__).resolve().parents[1]
METRICS = ("null_no_library", "among_named", "one_cause", "single_right", "told_right", "wrong_single")


def causes_when_partly(s: Summary) -> Summary:
    """``s`` with its verdict judged as if a partly explained gap were explained (its adequacy kept)."""
    v = s.verdict
    if v.adequacy != Adequacy.PARTLY_EXPLAINED:
        return s
    opts = s.options
    again = judge(s.hypotheses, share=1.0, min_share=opts.min_share, contender_ratio=opts.contender_ratio)
    return replace(s, verdict=replace(again, adequacy=v.adequacy, share_closed=v.share_closed))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out", type=Path, help="the development folder of gap_contact_dev.py")
    ap.add_argument("--name", help="the run whose summaries are judged again")
    ap.add_argument("--labels", type=Path, help="instead of --out/--name: a benchmark's labels")
    ap.add_argument("--reports", type=Path, nargs="+", help="... and the folders of its report folders")
    ap.add_argument("--probe-logs-only", action="store_true", help="judge again only the logs with probes")
    args = ap.parse_args(argv)
    design = yaml.safe_load((ROOT / "config.yaml").read_text())["gap"]["contact_benchmark"]
    if args.labels is not None and args.reports:
        labels = json.loads(args.labels.read_text())
        folders = args.reports
    elif args.out is not None and args.name:
        labels = json.loads((args.out / "labels.json").read_text())
        folders = sorted((args.out / "runs" / args.name).glob("shard*"))
    else:
        ap.error("give --out and --name, or --labels and --reports")
    summaries = find_summaries(labels, folders)

    def again(cid: str, s: Summary) -> Summary:
        return causes_when_partly(s) if not args.probe_logs_only or labels[cid].get("probes") else s

    for title, judged in (
        ("as judged", summaries),
        ("causes stated when partly explained", {k: again(k, s) for k, s in summaries.items()}),
    ):
        r = score_contact_cases(labels, judged, targets=design["targets"], min_size_sd=design["min_size_sd"])
        print(f"{title}: " + ", ".join(f"{k} {r[k]:.3f} (n {r['n_' + k]})" for k in METRICS))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
