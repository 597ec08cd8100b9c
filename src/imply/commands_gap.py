"""Gap-stage subcommands: ``imply diagnose`` and ``imply gap tables|generate|benchmark``.

``imply diagnose PUSHLOG.csv -o REPORT_DIR`` tells where a push table disagrees with
observed pushes, which unmodelled effect explains it and how far the gap shrinks once
that effect is added (see :mod:`imply.diagnose.analysis`); the report directory holds
``summary.json``, ``report.md``, ``residuals.csv`` and plots (:mod:`imply.diagnose.report`).
The baseline table defaults to ``results/table/table.npz``; the effect tables are
simulated on first use and cached (``--cache-dir``, default ``$IMPLY_CACHE`` or
``~/.cache/imply``).

To test the diagnostic on physics of your own, write a push log with a modified MJCF:
``imply sim export-xml -o my.xml``, edit it, then ``imply sim pushes PUSHES.csv --model
my.xml -o pushlog.csv`` and ``imply diagnose pushlog.csv -o report/``.

The benchmark commands are the workflow's (workflow/rules/gap.smk): ``gap tables``
builds the effect tables into the cache, ``gap generate`` writes synthetic push logs
with the label of each sealed in a separate file, ``gap benchmark`` scores the
diagnoses against the sealed labels and writes the stage's paper part.
"""

from __future__ import annotations

import argparse
import json
import logging
import os
from pathlib import Path

from imply.cli import UserError, int_range, json_arg, load_push_table, output_dir, positive_float

log = logging.getLogger("imply")

DEFAULT_TABLE = "results/table/table.npz"


def _cache_dir(arg: str | None) -> Path:
    if arg:
        return Path(arg)
    return Path(os.environ.get("IMPLY_CACHE") or Path.home() / ".cache" / "imply")


def register(sub: argparse._SubParsersAction) -> None:
    """Add this stage's subcommands to the imply parser."""
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

    g = sub.add_parser("gap", help="the diagnostic's benchmark (workflow steps)")
    gsub = g.add_subparsers(dest="gap_command", required=True)
    dm = gsub.add_parser(
        "diagnose-many",
        help="run 'imply diagnose' on several push logs in one process (one report folder per log, by file stem)",
    )
    dm.add_argument("pushlogs", nargs="+")
    dm.add_argument("-o", "--output", required=True, help="folder for the report folders")
    dm.add_argument("--force", action="store_true", help="as for 'imply diagnose', for each report folder")
    dm.add_argument("--table", default=DEFAULT_TABLE)
    dm.add_argument("--cache-dir")
    dm.add_argument("--effects")
    dm.add_argument("--effect-grid-json", type=json_arg)
    dm.add_argument("--options-json", type=json_arg)
    dm.add_argument("--threads", type=int, default=0)
    dm.set_defaults(func=cmd_diagnose_many)

    t = gsub.add_parser("tables", help="build (or find) the effect tables in the cache")
    t.add_argument("--table", default=DEFAULT_TABLE)
    t.add_argument("--cache-dir")
    t.add_argument("--effect-grid-json", type=json_arg)
    t.add_argument("--effects", help="comma-separated effects (default: the whole library)")
    t.add_argument("--options-json", type=json_arg, help="diagnostic settings (config gap.diagnose)")
    t.add_argument("--threads", type=int, default=0)
    t.add_argument("-o", "--output", required=True, help="manifest JSON to write (digest, model floor)")
    t.set_defaults(func=cmd_tables)

    gen = gsub.add_parser(
        "generate",
        help="the benchmark's push logs from the converged world (imply.realworld), labels sealed apart",
    )
    gen.add_argument("--table", default=DEFAULT_TABLE, help="its scene is the world's scene (its numbers are not read)")
    gen.add_argument("--bench-json", type=json_arg, required=True, help="config gap.benchmark")
    gen.add_argument("--logs", required=True, help="folder for the push logs (<log id>.csv)")
    gen.add_argument("--sealed", required=True, help="JSON file for the sealed labels")
    gen.add_argument("--accuracy", required=True, help="JSON file for the world's measured numerical error")
    gen.add_argument("--threads", type=int_range(0), default=0)
    gen.set_defaults(func=cmd_generate)

    b = gsub.add_parser("benchmark", help="score diagnoses against the sealed labels; write the stage's paper part")
    b.add_argument("--table", default=DEFAULT_TABLE)
    b.add_argument("--bench-json", type=json_arg, required=True)
    b.add_argument("--sealed", required=True)
    b.add_argument("--accuracy", required=True, help="the world's measured numerical error (from 'gap generate')")
    b.add_argument("--reports", required=True, nargs="+", help="folders holding one report folder per case")
    b.add_argument("-o", "--output", required=True, help="benchmark JSON")
    b.add_argument("--markdown", required=True, help="benchmark report (Markdown)")
    b.add_argument("--part", required=True, help="paper part JSON (results/paper/parts/gap.json)")
    b.set_defaults(func=cmd_benchmark)


def _load_table(path: str):
    hint = "build it with 'snakemake --cores 2 results/table/table.npz'" if path == DEFAULT_TABLE else ""
    return load_push_table(path, "--table", hint)


def _effects(arg: str | None):
    from imply.diagnose import candidates as C

    try:
        return C.get(None if not arg else [x.strip() for x in arg.split(",") if x.strip()])
    except KeyError as exc:
        raise UserError(f"--effects: {exc.args[0]}") from exc


def _options(args: argparse.Namespace):
    """Diagnostic options and effect-table grid from their JSON, checked before any work."""
    from dataclasses import fields

    from imply.config_check import ConfigError, unknown_keys
    from imply.diagnose.analysis import Options
    from imply.diagnose.tables import CoarseGrid

    for flag, value, cls in (("--options-json", args.options_json, Options),
                             ("--effect-grid-json", args.effect_grid_json, CoarseGrid)):  # fmt: skip
        if value is not None and not isinstance(value, dict):
            raise UserError(f"{flag}: expected a JSON object, not {type(value).__name__}")
        try:
            unknown_keys(value or {}, [f.name for f in fields(cls)], flag)
        except ConfigError as exc:
            raise UserError(str(exc)) from exc
    try:
        return Options.from_dict(args.options_json), CoarseGrid.from_dict(args.effect_grid_json)
    except (TypeError, ValueError) as exc:
        raise UserError(f"options: {exc}") from exc


def _diagnosis_setup(args: argparse.Namespace):
    """Table, candidate effects, options and effect tables of a diagnose call."""
    from imply.diagnose.candidates import library_effects, needs_across
    from imply.diagnose.tables import load_or_build

    table = _load_table(args.table)
    effects = _effects(args.effects)
    opts, grid = _options(args)
    if getattr(args, "noise_sd", None) is not None:
        opts = opts.replace(noise_sd=args.noise_sd)
    if getattr(args, "ignore_measured", False):
        opts = opts.replace(use_measured=False)
    etables = load_or_build(table, library_effects(effects), grid, _cache_dir(args.cache_dir), nthread=args.threads,
                            progress=True, across=needs_across(effects), stop_time=opts.use_stop_time)  # fmt: skip
    floor = etables.meta.get("model_floor") or {}
    if opts.model_floor is None:
        opts = opts.replace(model_floor=floor.get("rms"))
    if opts.stop_time_floor is None and floor.get("stop_time"):
        opts = opts.replace(stop_time_floor=floor["stop_time"]["rms"])
    return table, effects, opts, etables


def check_report_folder(output, force: bool, inputs) -> Path:
    """Refuse, before any work, a report folder whose writing would destroy files."""
    from imply.diagnose.report import REPORT_FILES
    from imply.io import OutputError, check_folder

    out = output_dir(output)
    try:
        check_folder(out, REPORT_FILES, force, inputs)
    except OutputError as exc:
        raise UserError(f"-o {exc}") from exc
    return out


def diagnose_file(pushlog_path, output, table, effects, opts, etables, force: bool = False) -> dict:
    """Diagnose one push log into the report folder ``output``; returns the summary.

    The report is written into a temporary sibling folder and moved into place (see
    :func:`imply.io.write_folder`): no half-written report, and nothing in ``output``
    that an earlier report did not write is touched.
    """
    from imply.diagnose.analysis import diagnose
    from imply.diagnose.fit import Problem
    from imply.diagnose.pushlog import read_pushlog
    from imply.diagnose.report import write_report
    from imply.io import write_folder
    from imply.tabular import InputError

    out = check_report_folder(output, force, [pushlog_path])
    try:
        pushlog = read_pushlog(pushlog_path, table.speed_range, mass_range=table.mass_range,
                               friction_range=table.friction_range)  # fmt: skip
    except InputError as exc:
        raise UserError(str(exc)) from exc
    prob = Problem(pushlog, table, etables, grid=opts.grid, use_measured=opts.use_measured,
                   use_stop_time=opts.use_stop_time)  # fmt: skip
    diag = diagnose(prob, effects, opts)
    write_folder(out, lambda tmp: write_report(diag, tmp), force=force)
    v = diag.summary["verdict"]
    log.info("%s: verdict %s (%s) -> %s", pushlog_path, v["verdict"], v["reason"], out)
    return diag.summary


def _check_pushlog(path, table) -> None:
    """Read a push log once before anything is simulated, so bad input fails fast."""
    from imply.diagnose.pushlog import read_pushlog
    from imply.tabular import InputError

    try:
        read_pushlog(path, table.speed_range, mass_range=table.mass_range, friction_range=table.friction_range)
    except InputError as exc:
        raise UserError(str(exc)) from exc


def cmd_diagnose(args: argparse.Namespace) -> int:
    check_report_folder(args.output, args.force, [args.pushlog, args.table])
    _check_pushlog(args.pushlog, _load_table(args.table))
    _options(args)
    _effects(args.effects)
    table, effects, opts, etables = _diagnosis_setup(args)
    diagnose_file(args.pushlog, args.output, table, effects, opts, etables, force=args.force)
    return 0


def cmd_diagnose_many(args: argparse.Namespace) -> int:
    from tqdm.auto import tqdm

    out = output_dir(args.output)
    stems: dict[str, str] = {}
    for path in args.pushlogs:
        stem = Path(path).stem
        if stem in stems:
            raise UserError(f"{path} and {stems[stem]} would share the report folder {out / stem}; rename one")
        stems[stem] = path
        check_report_folder(out / stem, args.force, [path, args.table])
    table = _load_table(args.table)
    for path in args.pushlogs:
        _check_pushlog(path, table)
    _options(args)
    _effects(args.effects)
    table, effects, opts, etables = _diagnosis_setup(args)
    for path in tqdm(args.pushlogs, desc="diagnoses", unit="log"):
        diagnose_file(path, out / Path(path).stem, table, effects, opts, etables, force=args.force)
    return 0


def cmd_tables(args: argparse.Namespace) -> int:
    from imply.diagnose.candidates import library_effects, needs_across
    from imply.diagnose.tables import load_or_build
    from imply.io import write_json

    table = _load_table(args.table)
    effects = _effects(args.effects)
    opts, grid = _options(args)
    et = load_or_build(table, library_effects(effects), grid, _cache_dir(args.cache_dir), nthread=args.threads,
                       progress=True, across=needs_across(effects), stop_time=opts.use_stop_time)  # fmt: skip
    write_json(args.output, {"meta": et.meta, "levels": {k: v.tolist() for k, v in et.levels.items()}})
    log.info("effect tables ready (model floor %.4f) -> %s", et.meta["model_floor_rms"], args.output)
    return 0


def _design(cfg: dict):
    from imply.realworld.cases import BenchmarkDesign

    if not isinstance(cfg, dict):
        raise UserError(f"--bench-json: expected a JSON object, not {type(cfg).__name__}")
    try:
        return BenchmarkDesign.from_dict(cfg)
    except (TypeError, ValueError) as exc:
        raise UserError(f"--bench-json: {exc}") from exc


def cmd_generate(args: argparse.Namespace) -> int:
    from imply.io import write_csv, write_json
    from imply.realworld.accuracy import measure_error
    from imply.realworld.cases import accuracy_sample, draw_cases, make_log, simulate_cases
    from imply.sim import SceneConfig

    design = _design(args.bench_json)
    acc = {"pushes": 48, "nominal": 16, "factor": 4, **(args.bench_json.get("accuracy") or {})}
    table = _load_table(args.table)
    scene = SceneConfig.from_dict(table.meta.get("scene"))
    cases = draw_cases(design)
    log.info("simulating %d logs (%d objects x %d speeds each) in the world", len(cases), design.n_objects,
             len(design.speeds))  # fmt: skip
    sims = simulate_cases(cases, design, scene, nthread=args.threads, progress=True)
    labels = {}
    for case in cases:
        frame, label = make_log(case, sims[case["id"]], design, scene)
        write_csv(Path(args.logs) / f"{case['id']}.csv", frame)
        labels[case["id"]] = label
    log.info("measuring the world's numerical error on %d of its pushes", acc["pushes"] + acc["nominal"])
    sample, nominal = accuracy_sample(cases, design, scene, int(acc["pushes"]), int(acc["nominal"]))
    error = measure_error(sample, nominal, scene, design.stepping, factor=int(acc["factor"]), nthread=args.threads,
                          progress=True)  # fmt: skip
    error["table_numerical_error"] = table.meta.get("numerical_error")
    error["stepping"] = design.stepping.__dict__
    write_json(args.accuracy, error)
    write_json(args.sealed, labels)
    e = error["against_finer"]["log_d"]
    log.info("wrote %d logs -> %s (labels sealed in %s); world error max %.4f RMS %.4f in log d", len(labels),
             args.logs, args.sealed, e["max_abs"], e["rms"])  # fmt: skip
    return 0


def cmd_benchmark(args: argparse.Namespace) -> int:
    from tqdm.auto import tqdm

    from imply.diagnose.benchmark import score_cases, visible_size
    from imply.diagnose.report_bench import write_benchmark
    from imply.io import write_json

    table = _load_table(args.table)
    with open(args.sealed) as fh:
        labels = json.load(fh)
    with open(args.accuracy) as fh:
        accuracy = json.load(fh)
    summaries = {}
    for cid in labels:
        found = [Path(r) / cid / "summary.json" for r in args.reports if (Path(r) / cid / "summary.json").is_file()]
        if not found:
            raise UserError(f"--reports: no diagnosis for log {cid} in {', '.join(args.reports)}")
        with open(found[0]) as fh:
            summaries[cid] = json.load(fh)
    sizes = {}
    for cid, lab in tqdm(labels.items(), desc="visible sizes", unit="log"):
        sizes[cid] = {what: visible_size(lab, table, what) for what in lab["noise_free"]}
    result = score_cases(labels, summaries, sizes, float(args.bench_json.get("min_size_sd", 2.0)))
    result["world_accuracy"] = accuracy
    write_json(args.output, result)
    write_benchmark(result, args.bench_json, args.markdown, args.part)
    log.info("false alarms %.3f (n=%d), top-1 %.3f (n=%d), both named %.3f (n=%d), none outside %.3f (n=%d), "
             "magnitude error %.3f, shrinkage %.3f", result["false_alarm"], result["n_null"], result["top1_big"],
             result["n_big"], result["both_named_big"], result["n_double_big"], result["none_recall_outside"],
             result["n_outside"], result["magnitude_rel_error_median"], result["shrinkage_median"])  # fmt: skip
    return 0
