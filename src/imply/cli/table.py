"""``imply table build|check``: the push table f(v, m, mu) -> log d, and its measured numerical error."""

from __future__ import annotations

import argparse
import logging

from imply.cli.common import (
    add_scene_options,
    config_from_json,
    config_section,
    int_range,
    json_arg,
    load_push_table,
    output_file,
    scene_from_args,
    user_errors,
)

log = logging.getLogger("imply")


def register(sub: argparse._SubParsersAction) -> None:
    t = sub.add_parser("table", help="build the push table f(v, m, mu) -> log d")
    tsub = t.add_subparsers(dest="table_command", required=True)
    tb = tsub.add_parser("build", help="simulate every cell and write the table")
    add_scene_options(tb)
    tb.add_argument("--grid-json", type=json_arg, help="table axes as JSON (config key 'table')")
    tb.add_argument("-o", "--output", required=True, help="the push table to write (.npz)")
    tb.add_argument("--threads", type=int_range(0), default=0, help="simulation threads (0: all CPUs)")
    tb.add_argument(
        "--check-json",
        type=json_arg,
        help="how to measure the table's numerical error, recorded in its metadata (config key 'table_check': "
        'cells, seed, reference_substeps; default {"cells": 200}; {"cells": 0} skips it)',
    )
    tb.set_defaults(func=cmd_table_build)
    tc = tsub.add_parser(
        "check",
        help="measure a table's numerical error against a much finer reference",
        description=(
            "Compares the table's log d at sampled grid nodes (the 8 corners of the range, then random ones) "
            "with the same scene stepped uniformly at a much finer step on a separate code path, and prints "
            "max and RMS of |delta log d| and the reference's own error estimate."
        ),
    )
    tc.add_argument("table", help="push table (.npz)")
    tc.add_argument("--cells", type=int_range(1), help="grid nodes to compare (default: TableCheckConfig.cells)")
    tc.add_argument("--seed", type=int_range(0), help="which random nodes (default: TableCheckConfig.seed)")
    tc.add_argument(
        "--reference-substeps",
        type=int_range(2),
        help="reference step = the table's timestep / this (default: TableCheckConfig.reference_substeps)",
    )
    tc.add_argument("-o", "--output", help="also write the result as JSON here")
    tc.add_argument("--threads", type=int_range(0), default=0, help="simulation threads (0: all CPUs)")
    tc.set_defaults(func=cmd_table_check)


def cmd_table_build(args: argparse.Namespace) -> int:
    from imply.config_check import ConfigError, table_grid
    from imply.table import TableCheckConfig, TableConfig, build_table, check_table, with_numerical_error

    output = output_file(args.output, [getattr(args, "config", None)])
    scene = scene_from_args(args, compile_model=True)
    grid_cfg, where = args.grid_json, "--grid-json"
    if grid_cfg is None and args.config:
        grid_cfg, where = config_section(args.config, "table"), f"--config {args.config}: table"
    with user_errors(ConfigError):
        grid = table_grid(grid_cfg, where) if grid_cfg is not None else TableConfig().grid()
    check = config_from_json(TableCheckConfig, args.check_json, "--check-json")
    # the simulator refuses settings it cannot finish a push with; a failed cell names itself
    with user_errors(ValueError, RuntimeError, message="cannot build the table: {error}"):
        table = build_table(scene, grid, nthread=args.threads, progress=True)
    if check.cells:
        log.info("measuring the table's numerical error on %d cells", check.cells)
        table = with_numerical_error(table, check_table(table, check, nthread=args.threads, progress=True))
        log.info("numerical error: %s", _error_line(table.meta["numerical_error"]))
    table.save(output)
    log.info("wrote %s", output)
    return 0


def _error_line(error: dict) -> str:
    worst = error["worst_cell"]
    return (
        f"max |delta log d| {error['max_abs_log_d']:.4f}, RMS {error['rms_log_d']:.4f} over {error['cells']} cells "
        f"(worst at v={worst['speed']:g}, m={worst['mass']:.3g}, mu={worst['friction']:.3g}); reference at "
        f"{error['reference_step_s'] * 1e6:.4g} us, its own error max {error['reference_error_max']:.4f}, "
        f"RMS {error['reference_error_rms']:.4f}"
    )


def cmd_table_check(args: argparse.Namespace) -> int:
    from imply.io import write_json
    from imply.table import TableCheckConfig, check_table

    output = output_file(args.output, [args.table]) if args.output else None
    table = load_push_table(args.table, option="TABLE")
    given = {"cells": args.cells, "seed": args.seed, "reference_substeps": args.reference_substeps}
    settings = TableCheckConfig(**{k: v for k, v in given.items() if v is not None})  # the rest: the class's defaults
    with user_errors(ValueError, message=f"cannot check {args.table}: {{error}}"):
        error = check_table(table, settings, nthread=args.threads, progress=True)
    recorded = table.meta.get("numerical_error")
    print(_error_line(error))
    if recorded:
        print(f"recorded in the table when built: {_error_line(recorded)}")
    if output is not None:
        write_json(output, error)
    return 0
