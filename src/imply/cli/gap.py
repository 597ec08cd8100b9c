"""``imply study gap tables|generate|lab-generate|merge-labels|diagnose-many|closed-loop|separability|lab-score|benchmark``.

The workflow's gap stage (``workflow/rules/gap.smk``): ``tables`` builds the effect
tables into a folder, ``generate`` writes synthetic push logs with each one's label
sealed in a separate file, ``lab-generate`` writes one set of the lab benchmark's logs (pushes with
calibration probes, on several engines) (each of the two can write one shard of the logs, ``--shard K --shards
N``, and ``merge-labels`` joins the shards' labels), ``separability`` marks its effect logs separable or not from
their contact and ``lab-score`` scores one set's diagnoses with and without its probes, ``diagnose-many`` runs ``imply diagnose`` on many logs in
one process, ``closed-loop`` runs the recommended next pushes of the logs with several
explanations in contention in their worlds and diagnoses again, ``benchmark`` scores the diagnoses against the sealed labels (a result
document the gap stage's numbers are read from) and writes the benchmark's report.
"""

from __future__ import annotations

import argparse

from imply.cli.common import (
    DEFAULT_TABLE,
    add_diagnose_options,
    int_range,
    json_arg,
)
from imply.cli.gap_diagnoses import cmd_closed_loop, cmd_diagnose_many
from imply.cli.gap_logs import cmd_generate, cmd_lab_generate, cmd_merge_labels, cmd_tables
from imply.cli.gap_scores import cmd_benchmark, cmd_lab_score, cmd_separability


def register(sub: argparse._SubParsersAction) -> None:
    g = sub.add_parser("gap", help="the diagnostic's benchmark (workflow steps)")
    gsub = g.add_subparsers(dest="gap_command", required=True)
    dm = gsub.add_parser(
        "diagnose-many",
        help="run 'imply diagnose' on several push logs in one process (one report folder per log, by file stem)",
    )
    dm.add_argument(
        "pushlogs",
        nargs="+",
        help="the push logs to diagnose (each with its .track.csv and .probes.csv where beside it), or folders of "
        "them (every .csv or .parquet in it but the tracks and probes)",
    )
    dm.add_argument("-o", "--output", required=True, help="folder for the report folders")
    dm.add_argument(
        "--references",
        metavar="DIR",
        help="a folder of reference sessions, one per log under the log's file name (with their .probes.csv beside "
        "them): each log is diagnosed against its own ('imply diagnose --reference')",
    )
    add_shard_options(
        dm, "diagnose", after="in the order given, a folder's logs sorted; each shard writes its own report folders"
    )
    add_diagnose_options(dm)
    dm.set_defaults(func=cmd_diagnose_many)

    t = gsub.add_parser("tables", help="build (or find) the effect tables in a folder, with a manifest")
    t.add_argument("--table", default=DEFAULT_TABLE, help="the push table (default results/table/table.npz)")
    t.add_argument("--effect-grid-json", type=json_arg, help="the effect tables' grids (config gap.effect_grid)")
    t.add_argument("--effects", help="comma-separated effects (default: the whole library)")
    t.add_argument("--options-json", type=json_arg, help="diagnostic settings (config gap.diagnose)")
    t.add_argument("--threads", type=int_range(0), default=0, help="simulation threads (0: all CPUs)")
    t.add_argument(
        "-o",
        "--output",
        required=True,
        help="folder of the effect tables (an effect-table cache) and their manifest.json",
    )
    t.set_defaults(func=cmd_tables)

    gen = gsub.add_parser(
        "generate",
        help="the benchmark's push logs from the converged world (imply.realworld; --contact-bench-json: with "
        "contact models of its own and another engine), labels sealed apart",
    )
    gen.add_argument("--table", default=DEFAULT_TABLE, help="its scene is the world's scene (its numbers are not read)")
    which = gen.add_mutually_exclusive_group(required=True)
    which.add_argument("--bench-json", type=json_arg, help="config gap.benchmark")
    which.add_argument(
        "--contact-bench-json",
        type=json_arg,
        help="config gap.contact_benchmark: worlds with a contact model of their own, and another engine's",
    )
    gen.add_argument("--logs", required=True, help="folder for the push logs (<log id>.csv)")
    gen.add_argument("--sealed", required=True, help="JSON file for the sealed labels (with --shards: the shard's)")
    gen.add_argument(
        "--accuracy",
        help="JSON file for the world's measured numerical error (required unless sharded; with --shards, give it "
        "to one shard: it is measured on a sample of every log's pushes, the same in any shard)",
    )
    gen.add_argument("--threads", type=int_range(0), default=0, help="simulation threads (0: all CPUs)")
    add_shard_options(gen)
    gen.set_defaults(func=cmd_generate)

    cl = gsub.add_parser(
        "closed-loop",
        help="run the next pushes of every log with several explanations in contention (and as many random pushes of "
        "its own design) in the same world, append them and diagnose again (the other-contact benchmark; the lab "
        "benchmark's, with the recommended probes too)",
    )
    which = cl.add_mutually_exclusive_group(required=True)
    which.add_argument("--contact-bench-json", type=json_arg, help="config gap.contact_benchmark")
    which.add_argument("--lab-json", type=json_arg, help="config gap.lab_benchmark (with --set): probes are allowed")
    cl.add_argument("--set", choices=("development", "sealed"), help="the lab benchmark's set (with --lab-json)")
    cl.add_argument("--logs", required=True, help="folder of the benchmark's push logs")
    cl.add_argument("--reports", required=True, help="folder of their report folders (one per log)")
    cl.add_argument("-o", "--output", required=True, help="folder for the appended logs and their reports")
    cl.add_argument(
        "--references",
        metavar="DIR",
        help="the logs' reference sessions (one per log under its file name): every diagnosis is against its own",
    )
    add_diagnose_options(cl)
    cl.set_defaults(func=cmd_closed_loop)

    lab = gsub.add_parser(
        "lab-generate",
        help="one set of the lab benchmark's logs: pushes with calibration probes, on MuJoCo contact variants, Bullet "
        "and SAPIEN (imply.realworld.lab)",
    )
    lab.add_argument(
        "--lab-json",
        type=json_arg,
        required=True,
        help="config gap.lab_benchmark (the other set's seed and logs may be left out)",
    )
    lab.add_argument("--set", required=True, choices=("development", "sealed"), help="which set")
    lab.add_argument("--table", default=DEFAULT_TABLE, help="its scene is the worlds' scene (its numbers are not read)")
    lab.add_argument(
        "--logs",
        required=True,
        help="folder for the push logs (<log id>.csv, .track.csv, and .probes.csv where probed)",
    )
    lab.add_argument(
        "--references",
        help="folder for each log's reference session (<log id>.csv, .probes.csv where probed): the same world and "
        "boxes without the effect, one push of each, fresh noise",
    )
    lab.add_argument("--labels", required=True, help="JSON file for the logs' labels (with --shards: the shard's)")
    lab.add_argument(
        "--timing", required=True, help="JSON file for each world's time per push (with --shards: the shard's)"
    )
    lab.add_argument(
        "--threads",
        type=int_range(0),
        default=0,
        help="MuJoCo's simulation threads (0: all CPUs; the other engines use one)",
    )
    add_shard_options(lab)
    lab.set_defaults(func=cmd_lab_generate)

    ml = gsub.add_parser(
        "merge-labels",
        help="join the labels (and the lab's timings) that the shards of 'imply study gap generate' or 'imply study gap "
        "lab-generate' wrote into what one unsharded run writes",
    )
    ml.add_argument("parts", nargs="+", help="the shards' labels files")
    ml.add_argument("-o", "--output", required=True, help="JSON file for the joined labels")
    ml.add_argument("--timing", nargs="+", default=[], help="the shards' timing files (lab-generate)")
    ml.add_argument("--timing-output", help="JSON file for the joined timing (with --timing)")
    ml.set_defaults(func=cmd_merge_labels)

    sep = gsub.add_parser(
        "separability",
        help="mark each lab-benchmark effect log separable or not from its contact, per observable set, from its "
        "label (a result document and a report)",
    )
    sep.add_argument("--lab-json", type=json_arg, required=True, help="config gap.lab_benchmark")
    sep.add_argument(
        "--labels",
        nargs="+",
        required=True,
        metavar="SET=LABELS",
        help="each set's labels, as development=PATH sealed=PATH",
    )
    sep.add_argument("--timing", nargs="+", required=True, metavar="SET=TIMING", help="each set's timing, likewise")
    sep.add_argument("-o", "--output", required=True, help="the result document (JSON)")
    sep.add_argument("--markdown", required=True, help="the report (Markdown)")
    sep.set_defaults(func=cmd_separability)

    ls = gsub.add_parser(
        "lab-score",
        help="score one lab-benchmark set's diagnoses: alone, with its probes and against its reference sessions "
        "(a result document and a report)",
    )
    ls.add_argument("--table", default=DEFAULT_TABLE, help="the push table (the true share of each log's gap)")
    ls.add_argument("--lab-json", type=json_arg, required=True, help="config gap.lab_benchmark (its targets)")
    ls.add_argument("--set", required=True, choices=("development", "sealed"), help="which set")
    ls.add_argument("--labels", required=True, help="the set's labels ('imply study gap lab-generate')")
    ls.add_argument("--reports-probes", required=True, help="the folder of its report folders, diagnosed with probes")
    ls.add_argument("--reports-no-probes", required=True, help="the same diagnosed without them")
    ls.add_argument(
        "--reports-reference", nargs="+", help="the same diagnosed against their reference sessions (folders of shards)"
    )
    ls.add_argument(
        "--closed-loop",
        nargs="*",
        default=[],
        help="folders written by 'imply study gap closed-loop --lab-json' on this set",
    )
    ls.add_argument("-o", "--output", required=True, help="the result document (JSON)")
    ls.add_argument("--markdown", required=True, help="the report (Markdown)")
    ls.set_defaults(func=cmd_lab_score)

    b = gsub.add_parser("benchmark", help="score diagnoses against the sealed labels (a result document)")
    b.add_argument("--table", default=DEFAULT_TABLE, help="the push table (default results/table/table.npz)")
    b.add_argument("--bench-json", type=json_arg, required=True, help="config gap.benchmark (its targets)")
    b.add_argument("--sealed", required=True, help="the sealed labels of 'imply study gap generate'")
    b.add_argument("--accuracy", required=True, help="the world's measured numerical error (from 'gap generate')")
    b.add_argument("--reports", required=True, nargs="+", help="folders holding one report folder per case")
    b.add_argument("-o", "--output", required=True, help="the benchmark's result document (JSON)")
    b.add_argument("--markdown", required=True, help="benchmark report (Markdown)")
    b.add_argument("--contact-bench-json", type=json_arg, help="config gap.contact_benchmark (its targets)")
    b.add_argument("--contact-sealed", help="the contact benchmark's sealed labels")
    b.add_argument("--contact-reports", nargs="+", default=[], help="folders of the contact benchmark's reports")
    b.add_argument(
        "--observed-reports",
        nargs="+",
        default=[],
        help="folders of the same logs' reports with every observable the logs carry (the pusher's measured speed, "
        "the box's track), scored beside the others",
    )
    b.add_argument(
        "--observed-contact-reports",
        nargs="+",
        default=[],
        help="the same for the contact benchmark's logs",
    )
    b.add_argument("--closed-loop", nargs="+", default=[], help="folders written by 'imply study gap closed-loop'")
    b.set_defaults(func=cmd_benchmark)


def add_shard_options(
    parser: argparse.ArgumentParser,
    verb: str = "write",
    *,
    after: str = "join the labels with 'imply study gap merge-labels'",
) -> None:
    """``--shard K --shards N``: ``verb`` only the logs whose index in the set is K modulo N (imply.realworld.shards);
    ``after``: what the help says of the shards and their outputs."""
    parser.add_argument(
        "--shards",
        type=int_range(1),
        default=1,
        help=f"split the logs into this many shards and {verb} one ({after})",
    )
    parser.add_argument(
        "--shard",
        type=int_range(0),
        default=0,
        help=f"which shard to {verb} (0 .. shards-1): logs whose index is K mod N",
    )
