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
import logging
import os
from pathlib import Path

from imply.cli.common import (
    UserError,
    config_from_json,
    int_range,
    json_arg,
    load_push_table,
    output_dir,
    positive_float,
)

log = logging.getLogger("imply")

DEFAULT_TABLE = "results/table/table.npz"


def register(sub: argparse._SubParsersAction) -> None:
    d = sub.add_parser(
        "diagnose",
        help="locate the sim-to-real gap of a push log and rank unmodelled effects that explain it",
        description=(
            "PUSHLOG (CSV or parquet): object_id,speed,displacement (m/s, m) and optional direction (rad), "
            "stop_time, size_x,size_y,size_z, mass, friction (measured mass/friction are held fixed instead of "
            "fitted). Writes REPORT_DIR/summary.json, report.md, residuals.csv and plots into a new (or empty) "
            "folder; with --force, into a folder holding an earlier report, whose files alone are replaced."
        ),
    )
    d.add_argument("pushlog")
    d.add_argument("-o", "--output", required=True, help="report folder to write (new or empty)")
    d.add_argument("--force", action="store_true",
                   help="write into a non-empty folder: replace the files an earlier report wrote there, keep the rest")  # fmt: skip
    d.add_argument("--table", default=DEFAULT_TABLE, help="baseline push table (default %(default)s)")
    d.add_argument("--cache-dir", help="effect-table cache (default $IMPLY_CACHE or ~/.cache/imply)")
    d.add_argument("--effects", help="comma-separated candidate effects (default: the whole library)")
    d.add_argument(
        "--effect-grid-json", type=json_arg, help="coarse grid of the effect tables (config gap.effect_grid)"
    )
    d.add_argument("--options-json", type=json_arg, help="diagnostic settings (config gap.diagnose)")
    d.add_argument("--noise-sd", type=positive_float,
                   help="log-displacement noise sd, used when the log has no replicates")  # fmt: skip
    d.add_argument("--ignore-measured", action="store_true",
                   help="fit mass and friction even where the log has measured values")  # fmt: skip
    d.add_argument("--threads", type=int_range(0), default=0, help="simulation threads for building effect tables")
    d.set_defaults(func=cmd_diagnose)


def cache_dir(arg: str | None) -> Path:
    """The effect-table cache: ``--cache-dir``, else ``$IMPLY_CACHE``, else ``~/.cache/imply``."""
    if arg:
        return Path(arg)
    return Path(os.environ.get("IMPLY_CACHE") or Path.home() / ".cache" / "imply")


def load_table(path: str):
    hint = "build it with 'snakemake --cores 2 results/table/table.npz'" if path == DEFAULT_TABLE else ""
    return load_push_table(path, "--table", hint)


def candidate_effects(arg: str | None):
    """The candidates of ``--effects`` (all of the library when absent)."""
    from imply.diagnose import candidates

    try:
        return candidates.get(None if not arg else [x.strip() for x in arg.split(",") if x.strip()])
    except KeyError as exc:
        raise UserError(f"--effects: {exc.args[0]}") from exc


def options(args: argparse.Namespace):
    """Diagnostic options and effect-table grid from their JSON (and flags), checked before any work."""
    from imply.diagnose.analysis import DiagnosisConfig
    from imply.diagnose.effect_tables import CoarseGrid

    opts = config_from_json(DiagnosisConfig, args.options_json, "--options-json")
    grid = config_from_json(CoarseGrid, args.effect_grid_json, "--effect-grid-json")
    if getattr(args, "noise_sd", None) is not None:
        opts = opts.replace(noise_sd=args.noise_sd)
    if getattr(args, "ignore_measured", False):
        opts = opts.replace(use_measured=False)
    return opts, grid


def report_folder(output, force: bool, inputs) -> Path:
    """Refuse, before any work, a report folder whose writing would destroy files."""
    from imply.diagnose.run import check_report_folder
    from imply.io import OutputError

    out = output_dir(output)
    try:
        check_report_folder(out, force, inputs)
    except OutputError as exc:
        raise UserError(f"-o {exc}") from exc
    return out


def check_pushlog(path, table) -> None:
    """Read a push log once before anything is simulated, so bad input fails fast."""
    from imply.diagnose.run import read_checked_pushlog
    from imply.input_files import InputError

    try:
        read_checked_pushlog(path, table)
    except InputError as exc:
        raise UserError(str(exc)) from exc


def session(args: argparse.Namespace, table):
    """The diagnoses' shared setup (:func:`imply.diagnose.run.prepare`) from the options."""
    from imply.diagnose.run import prepare

    opts, grid = options(args)
    return prepare(table, candidate_effects(args.effects), opts, grid, cache_dir(args.cache_dir), nthread=args.threads)


def diagnose_one(path, output, sess, force: bool) -> dict:
    from imply.diagnose.run import diagnose_file
    from imply.input_files import InputError
    from imply.io import OutputError

    try:
        return diagnose_file(path, output, sess, force=force)
    except InputError as exc:
        raise UserError(str(exc)) from exc
    except OutputError as exc:
        raise UserError(f"-o {exc}") from exc


def cmd_diagnose(args: argparse.Namespace) -> int:
    report_folder(args.output, args.force, [args.pushlog, args.table])
    table = load_table(args.table)
    check_pushlog(args.pushlog, table)
    options(args)
    candidate_effects(args.effects)
    diagnose_one(args.pushlog, args.output, session(args, table), args.force)
    return 0
