"""``imply score``: the anchored consistency score of a user's rollout sets."""

from __future__ import annotations

import argparse
import logging
import os

from imply.cli.common import int_range, load_push_table, output_file, positive_float, user_errors
from imply.options import default_of
from imply.score import ScoreConfig

log = logging.getLogger("imply")

# the search grid's cached rows take 24 grid^2 bytes per distinct speed, and a block of
# the exhaustive search 8 grid^2 bytes per set in it: 1001 keeps both in the hundreds of MB
MAX_GRID = 1001


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "score",
        help="score rollout sets: self and anchored disagreement per object",
        description="Reads ROLLOUTS (object_id,role,speed,displacement; role calibration|rollout; one row per "
        "object, role and speed) and writes one row of scores per object.",
    )
    p.add_argument("rollouts", help="CSV with object_id,role,speed,displacement (role: calibration|rollout; metres)")
    p.add_argument("--table", required=True, help="push table (.npz) from 'imply table build'")
    p.add_argument("-o", "--output", required=True, help="scores CSV to write (not one of the inputs)")
    p.add_argument(
        "--floor",
        type=positive_float,
        default=default_of(ScoreConfig, "readout_floor"),
        help="readout floor in metres (default %(default)g)",
    )
    p.add_argument(
        "--grid",
        type=int_range(2, MAX_GRID),
        default=default_of(ScoreConfig, "grid"),
        help=f"search grid points per axis, 2 to {MAX_GRID} (default %(default)d)",
    )
    p.add_argument("--threads", type=int_range(0), default=0, help="scoring threads (0: all CPUs)")
    p.set_defaults(func=cmd_score)


def cmd_score(args: argparse.Namespace) -> int:
    from imply.input_files import InputError
    from imply.io import write_columns
    from imply.score import Scorer
    from imply.score_file import read_rollouts, score_rows
    from imply.table import OutOfRangeError

    output = output_file(args.output, [args.rollouts, args.table])
    table = load_push_table(args.table)
    with user_errors(InputError, OutOfRangeError):
        rows = read_rollouts(args.rollouts, table)
        threads = args.threads or os.cpu_count() or 1
        out = score_rows(rows, Scorer(table, grid=args.grid, floor=args.floor, threads=threads))
    write_columns(output, out)
    log.info("scored %d objects -> %s", len(rows.objects), output)
    return 0
