"""``imply diagnose PUSHLOG -o REPORT_DIR``: where the table disagrees with observed pushes, which unmodelled
effect explains it, and how far the gap shrinks once it is added.

The report folder holds ``summary.json``, ``report.md``, ``residuals.csv`` and plots
(:mod:`imply.diagnose.report`). The baseline table defaults to
``results/table/table.npz``; effect tables are simulated on first use and cached
(``--cache-dir``, default ``$IMPLY_CACHE`` or ``~/.cache/imply``). To test the
diagnostic on physics of your own: ``imply sim export-xml -o my.xml``, edit it, then
``imply sim pushes PUSHES.csv --model my.xml -o pushlog.csv`` and diagnose that.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from imply.cli.common import add_diagnose_options, diagnose_request


def register(sub: argparse._SubParsersAction) -> None:
    d = sub.add_parser(
        "diagnose",
        help="locate the sim-to-real gap of a push log and rank unmodelled effects that explain it",
        description=(
            "PUSHLOG (CSV or parquet): object_id,speed,displacement (m/s, m) and optional direction (rad), "
            "stop_time, pusher_speed, size_x,size_y,size_z, mass, friction (measured mass/friction are held fixed "
            "instead of fitted), push (numbers the tracks refer to); the boxes' tracks in a second file (--track, or "
            "<log>.track.csv beside it) and the calibration probes in a third (<log>.probes.csv beside it). "
            "Writes into the report folder (new or empty; with --force, one holding an earlier report, whose files "
            "alone are replaced): report.md (the verdict first), summary.json (every number), residuals.csv, "
            "next_pushes.csv (the pushes that would best tell the leading explanations apart), next_probes.csv "
            "(the calibration probe that would tell them apart better than any push, where one would), and the figures "
            "residuals_vs_speed.png, before_after.png, ranking.png and hypotheses.png; where a cause is stated, "
            "corrected.xml (the scene with the causes written in, the log's pushes re-simulated in it)."
        ),
    )
    d.add_argument(
        "pushlog", help="the push log (CSV or parquet; a .track.csv and a .probes.csv beside it are read with it)"
    )
    d.add_argument("-o", "--output", required=True, help="report folder to write (new or empty)")
    d.add_argument(
        "--track",
        help="the boxes' tracks (CSV or parquet, rows object_id,push,t,x,y[,yaw]; default: "
        "PUSHLOG's <stem>.track.csv or .parquet beside it, where there is one)",
    )
    d.add_argument(
        "--reference",
        metavar="REF",
        help="a reference session: a push log of the same robot and boxes (matched by object_id), recorded before "
        "the change to explain, with its own .track.csv and .probes.csv beside it where it has them. The report "
        "then gives the standing gap (read from REF), what changed since, and how far the gap shrinks",
    )
    d.add_argument(
        "--model",
        metavar="MJCF",
        help="the push scene the stated causes are written into (corrected.xml) and the log's pushes re-simulated "
        "in, with the names the simulator needs (see imply sim export-xml); default: the table's built-in scene",
    )
    d.add_argument(
        "--refit",
        action="store_true",
        help="also refit the stated causes and the boxes in the simulator (mujoco.sysid), for the simulator's own "
        "estimate and 95%% interval beside the tables' (tens of passes over the log)",
    )
    add_diagnose_options(d)
    d.set_defaults(func=cmd_diagnose)


def cmd_diagnose(args: argparse.Namespace) -> int:
    from imply.diagnose.run import run

    run(diagnose_request(args, [(args.pushlog, Path(args.output), args.reference)]))
    return 0
