"""``imply gap tables|generate|lab-generate|merge-labels|diagnose-many|closed-loop|separability|lab-score|benchmark``.

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
import json
import logging
from pathlib import Path

from imply.cli.common import (
    DEFAULT_TABLE,
    UserError,
    add_diagnose_options,
    candidate_effects,
    config_from_json,
    diagnose_request,
    diagnosis_options,
    int_range,
    json_arg,
    load_table,
    output_dir,
    user_errors,
)

log = logging.getLogger("imply")


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
        help="join the labels (and the lab's timings) that the shards of 'imply gap generate' or 'imply gap "
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
    ls.add_argument("--labels", required=True, help="the set's labels ('imply gap lab-generate')")
    ls.add_argument("--reports-probes", required=True, help="the folder of its report folders, diagnosed with probes")
    ls.add_argument("--reports-no-probes", required=True, help="the same diagnosed without them")
    ls.add_argument("--reports-reference", help="the same diagnosed against their reference sessions")
    ls.add_argument(
        "--closed-loop", nargs="*", default=[], help="folders written by 'imply gap closed-loop --lab-json' on this set"
    )
    ls.add_argument("-o", "--output", required=True, help="the result document (JSON)")
    ls.add_argument("--markdown", required=True, help="the report (Markdown)")
    ls.set_defaults(func=cmd_lab_score)

    b = gsub.add_parser("benchmark", help="score diagnoses against the sealed labels (a result document)")
    b.add_argument("--table", default=DEFAULT_TABLE, help="the push table (default results/table/table.npz)")
    b.add_argument("--bench-json", type=json_arg, required=True, help="config gap.benchmark (its targets)")
    b.add_argument("--sealed", required=True, help="the sealed labels of 'imply gap generate'")
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
    b.add_argument("--closed-loop", nargs="+", default=[], help="folders written by 'imply gap closed-loop'")
    b.set_defaults(func=cmd_benchmark)


def add_shard_options(parser: argparse.ArgumentParser) -> None:
    """``--shard K --shards N``: write only the logs whose index in the set is K modulo N (imply.realworld.shards)."""
    parser.add_argument(
        "--shards",
        type=int_range(1),
        default=1,
        help="split the logs into this many shards and write one (join the labels with 'imply gap merge-labels')",
    )
    parser.add_argument(
        "--shard",
        type=int_range(0),
        default=0,
        help="which shard to write (0 .. shards-1): logs whose index is K mod N",
    )


def _check_shard(args: argparse.Namespace) -> None:
    if args.shard >= args.shards:
        raise UserError(f"--shard {args.shard}: need 0 <= shard < --shards {args.shards}")


def _benchmark_config(args: argparse.Namespace):
    from imply.realworld.cases import BenchmarkConfig

    return config_from_json(BenchmarkConfig, args.bench_json, "gap.benchmark")


def cmd_diagnose_many(args: argparse.Namespace) -> int:
    from imply.diagnose.run import run

    out = output_dir(args.output)
    stems: dict[str, str] = {}
    pushlogs = [str(p) for path in args.pushlogs for p in logs_in(path)]
    if not pushlogs:
        raise UserError(f"no push logs in {', '.join(args.pushlogs)}")
    for path in pushlogs:
        stem = Path(path).stem
        if stem in stems:
            raise UserError(f"{path} and {stems[stem]} would share the report folder {out / stem}; rename one")
        stems[stem] = path
    refs: list[str | None] = [None] * len(pushlogs)
    if args.references is not None:
        folder = Path(args.references)
        if not folder.is_dir():
            raise UserError(f"--references {folder}: no such folder")
        refs = [str(folder / Path(path).name) for path in pushlogs]
        missing = [r for r in refs if not Path(r).is_file()]
        if missing:
            raise UserError(f"--references {folder}: no reference session {Path(missing[0]).name} for its log")
    run(diagnose_request(args, [(path, out / Path(path).stem, ref) for path, ref in zip(pushlogs, refs, strict=True)]))
    return 0


def logs_in(path: str) -> list[Path]:
    """A push log path as given, or a folder's push logs (sorted; its tracks and probes left to their logs)."""
    p = Path(path)
    if not p.is_dir():
        return [p]
    return sorted(
        f
        for f in p.iterdir()
        if f.suffix in (".csv", ".parquet") and not f.stem.endswith((".track", ".probes")) and f.is_file()
    )


def cmd_closed_loop(args: argparse.Namespace) -> int:
    from imply.diagnose.run import prepare
    from imply.realworld.cases import ContactBenchmarkConfig, draw_cases
    from imply.realworld.closed_loop import run_closed_loop
    from imply.realworld.lab import LabBenchmarkConfig, draw_lab_cases
    from imply.sim import SceneConfig

    if args.lab_json is not None:
        if args.set is None:
            raise UserError("--lab-json needs --set (development or sealed)")
        with user_errors(ValueError, TypeError, message="--lab-json: {error}"):
            design = LabBenchmarkConfig.of_subset(args.lab_json, args.set)
        drawn = draw_lab_cases(design)
    else:
        if args.set is not None:
            raise UserError("--set is the lab benchmark's (with --lab-json)")
        design = config_from_json(ContactBenchmarkConfig, args.contact_bench_json, "gap.contact_benchmark")
        drawn = draw_cases(design)
    for name in ("logs", "reports", "references"):
        if getattr(args, name) is not None and not Path(getattr(args, name)).is_dir():
            raise UserError(f"--{name} {getattr(args, name)}: no such folder")
    out = output_dir(args.output)
    request = diagnose_request(args, [])
    scene = SceneConfig.from_dict(request.table.meta.get("scene"), "the table's scene")
    rows = run_closed_loop(
        design=design,
        drawn=drawn,
        scene=scene,
        logs=Path(args.logs),
        reports=Path(args.reports),
        session=prepare(request),
        out=out,
        references=Path(args.references) if args.references else None,
        nthread=args.threads,
    )
    log.info("closed loop: %d logs x 2 arms diagnosed again -> %s", len(rows) // 2, out)
    return 0


def cmd_tables(args: argparse.Namespace) -> int:
    from imply.diagnose.run import effect_tables
    from imply.io import write_json

    table = load_table(args.table)
    opts, grid = diagnosis_options(args.options_json, args.effect_grid_json)
    folder = output_dir(args.output)
    et = effect_tables(
        table, candidate_effects(args.effects), options=opts, grid=grid, cache_dir=folder, nthread=args.threads
    )
    write_json(folder / "manifest.json", {"meta": et.meta, "levels": {k: v.tolist() for k, v in et.levels.items()}})
    log.info("effect tables ready (model floor %.4f) -> %s", et.meta["model_floor_rms"], folder)
    return 0


def _generate_config(args: argparse.Namespace):
    from imply.realworld.cases import ContactBenchmarkConfig

    if args.contact_bench_json is not None:
        return config_from_json(ContactBenchmarkConfig, args.contact_bench_json, "gap.contact_benchmark")
    return _benchmark_config(args)


def cmd_generate(args: argparse.Namespace) -> int:
    from imply.realworld.cases import write_benchmark_logs
    from imply.sim import SceneConfig

    _check_shard(args)
    if args.accuracy is None and args.shards == 1:
        raise UserError("--accuracy is required (unless sharded: then one shard measures it)")
    config = _generate_config(args)
    table = load_table(args.table)
    scene = SceneConfig.from_dict(table.meta.get("scene"), "the table's scene")
    error = write_benchmark_logs(
        config,
        scene,
        logs=Path(args.logs),
        sealed=Path(args.sealed),
        accuracy=None if args.accuracy is None else Path(args.accuracy),
        table_error=table.meta.get("numerical_error"),
        nthread=args.threads,
        progress=True,
        shard=args.shard,
        shards=args.shards,
    )
    log.info(
        "wrote the logs%s -> %s (labels sealed in %s)",
        f" of shard {args.shard} of {args.shards}" if args.shards > 1 else "",
        args.logs,
        args.sealed,
    )
    if error is not None:
        e = error["against_finer"]["log_d"]
        log.info("world error max %.4f RMS %.4f in log d -> %s", e["max_abs"], e["rms"], args.accuracy)
    return 0


def _lab_config(args: argparse.Namespace):
    from imply.realworld.lab import LabBenchmarkConfig

    return config_from_json(LabBenchmarkConfig, args.lab_json, "gap.lab_benchmark")


def cmd_lab_generate(args: argparse.Namespace) -> int:
    from imply.realworld.lab import LabBenchmarkConfig, write_lab_set
    from imply.sim import SceneConfig

    _check_shard(args)
    with user_errors(ValueError, TypeError, message="--lab-json: {error}"):
        design = LabBenchmarkConfig.of_subset(args.lab_json, args.set)
    table = load_table(args.table)
    scene = SceneConfig.from_dict(table.meta.get("scene"), "the table's scene")
    timing = write_lab_set(
        design,
        scene,
        logs=Path(args.logs),
        labels=Path(args.labels),
        timing=Path(args.timing),
        references=Path(args.references) if args.references else None,
        nthread=args.threads,
        progress=True,
        shard=args.shard,
        shards=args.shards,
    )
    for engine, t in timing.items():
        log.info("%s: %d pushes, %.4f s per push", engine, t["pushes"], t["seconds_per_push"])
    log.info(
        "wrote the %s set's logs%s -> %s (labels in %s)",
        args.set,
        f" of shard {args.shard} of {args.shards}" if args.shards > 1 else "",
        args.logs,
        args.labels,
    )
    return 0


def cmd_merge_labels(args: argparse.Namespace) -> int:
    from imply.io import write_json
    from imply.realworld.shards import merge_labels, merge_timing

    if bool(args.timing) != (args.timing_output is not None):
        raise UserError("--timing and --timing-output go together")

    def read(path: str) -> dict:
        try:
            with open(path) as fh:
                return json.load(fh)
        except (OSError, json.JSONDecodeError) as exc:
            raise UserError(f"{path}: {exc}") from exc

    with user_errors(ValueError, message="merge-labels: {error}"):
        labels = merge_labels([read(p) for p in args.parts])
    write_json(args.output, labels)
    if args.timing:
        write_json(args.timing_output, merge_timing([read(p) for p in args.timing]))
    log.info("joined %d labels from %d parts -> %s", len(labels), len(args.parts), args.output)
    return 0


def _set_paths(values: list[str], option: str) -> dict[str, str]:
    """``["development=a.json", "sealed=b.json"]`` -> ``{"development": "a.json", ...}``, refusing anything else."""
    from imply.realworld.lab import SETS

    out: dict[str, str] = {}
    for value in values:
        name, sep, path = value.partition("=")
        if not sep or name not in SETS or not path:
            raise UserError(f"{option}: {value!r} is not SET=PATH with SET one of {', '.join(SETS)}")
        if name in out:
            raise UserError(f"{option}: the {name} set is given twice")
        out[name] = path
    return out


def cmd_separability(args: argparse.Namespace) -> int:
    from imply.paper.results import write_result
    from imply.realworld.separability import mark_logs, summarise, write_separability

    design = _lab_config(args)
    labels, timing = _set_paths(args.labels, "--labels"), _set_paths(args.timing, "--timing")
    if set(labels) != set(timing):
        raise UserError("--labels and --timing must name the same sets")
    result = {
        "alias_cos": design.alias_cos,
        "min_size_sd": design.min_size_sd,
        "within": design.targets["magnitude_within"],
        "sets": {},
    }
    for name, path in labels.items():
        with user_errors(FileNotFoundError, message="--labels: {error}"):
            with open(path) as fh:
                marks = mark_logs(
                    json.load(fh),
                    alias_cos=design.alias_cos,
                    min_size_sd=design.min_size_sd,
                    crossing_sd=design.crossing_sd,
                    within=design.targets["magnitude_within"],
                )
        with user_errors(FileNotFoundError, message="--timing: {error}"):
            with open(timing[name]) as fh:
                times = json.load(fh)
        result["sets"][name] = {"logs": marks, "summary": summarise(marks), "timing": times}
        for engine, row in result["sets"][name]["summary"].items():
            log.info(
                "%s set, %s: %d effect logs; separable with displacement only %d, with probes %d",
                name,
                engine,
                row["effect_logs"],
                row["sets"]["displacement"]["separable"],
                row["sets"]["probes"]["separable"],
            )
    write_result(args.output, mark_logs, result)
    write_separability(result, args.markdown)
    return 0


def cmd_lab_score(args: argparse.Namespace) -> int:
    from imply.paper.results import write_result
    from imply.realworld.benchmark import CONTACT_SINGLE, find_summaries, shrink_sizes
    from imply.realworld.lab_score import score_lab, write_lab_score

    design = _lab_config(args)
    with user_errors(FileNotFoundError, message="--labels: {error}"):
        with open(args.labels) as fh:
            labels = json.load(fh)
    summaries = {}
    tiers = (
        ("no_probes", args.reports_no_probes),
        ("probes", args.reports_probes),
        ("reference", args.reports_reference),
    )
    for variant, folder in tiers:
        if folder is None:
            continue
        with user_errors(FileNotFoundError, message=f"--reports-{variant.replace('_', '-')}: {{error}}"):
            summaries[variant] = find_summaries(labels, [Path(folder)])
    result = score_lab(
        labels,
        summaries,
        targets=design.targets,
        min_size_sd=design.min_size_sd,
        alias_cos=design.alias_cos,
        crossing_sd=design.crossing_sd,
        sizes=shrink_sizes(labels, load_table(args.table), CONTACT_SINGLE),
    )
    if args.closed_loop:
        from imply.realworld.closed_loop import score_closed_loop

        with user_errors(FileNotFoundError, message="--closed-loop: {error}"):
            result["closed_loop"] = score_closed_loop(
                labels,
                [Path(p) for p in args.closed_loop],
                within=design.targets["magnitude_within"],
                min_size_sd=design.min_size_sd,
            )
    for variant in summaries:
        r = result[variant]["all"]
        log.info(
            "%s set, %s: nulls stating no effect %.2f, one cause right %.2f, contact named %.2f, shrink within %.2f",
            args.set,
            variant,
            r["null_no_library"],
            r["single_right"],
            r["contact_named"],
            r["shrink_within"],
        )
    write_result(args.output, score_lab, result)
    write_lab_score(result, args.set, args.markdown)
    return 0


def cmd_benchmark(args: argparse.Namespace) -> int:
    from imply.paper.results import write_result
    from imply.realworld.benchmark import find_summaries, score_cases, visible_sizes
    from imply.realworld.benchmark_report import write_benchmark_markdown

    table = load_table(args.table)
    config = _benchmark_config(args)
    with open(args.sealed) as fh:
        labels = json.load(fh)
    with open(args.accuracy) as fh:
        accuracy = json.load(fh)
    with user_errors(FileNotFoundError, message="--reports: {error}"):
        summaries = find_summaries(labels, [Path(r) for r in args.reports])
    visible = visible_sizes(labels, table)
    result = score_cases(labels, summaries, visible, config=config, accuracy=accuracy)
    if args.contact_sealed:
        from imply.realworld.benchmark import CONTACT_SINGLE, score_contact_cases, shrink_sizes

        if args.contact_bench_json is None or not args.contact_reports:
            raise UserError("--contact-sealed needs --contact-bench-json and --contact-reports")
        with open(args.contact_sealed) as fh:
            contact_labels = json.load(fh)
        with user_errors(FileNotFoundError, message="--contact-reports: {error}"):
            contact_summaries = find_summaries(contact_labels, [Path(r) for r in args.contact_reports])
        from imply.realworld.cases import ContactBenchmarkConfig

        design = config_from_json(ContactBenchmarkConfig, args.contact_bench_json, "gap.contact_benchmark")
        result["contact"] = score_contact_cases(
            contact_labels,
            contact_summaries,
            targets=dict(design.targets),
            min_size_sd=design.min_size_sd,
            sizes=shrink_sizes(contact_labels, table, CONTACT_SINGLE),
        )
        if args.closed_loop:
            from imply.realworld.closed_loop import score_closed_loop

            result["contact"]["closed_loop"] = score_closed_loop(
                contact_labels,
                [Path(p) for p in args.closed_loop],
                within=design.targets["magnitude_within"],
                min_size_sd=design.min_size_sd,
            )
    if args.observed_reports:
        with user_errors(FileNotFoundError, message="--observed-reports: {error}"):
            observed = find_summaries(labels, [Path(r) for r in args.observed_reports])
        result["observed"] = score_cases(labels, observed, visible, config=config, accuracy=accuracy)
        if args.observed_contact_reports and args.contact_sealed:
            from imply.realworld.benchmark import score_contact_cases

            with user_errors(FileNotFoundError, message="--observed-contact-reports: {error}"):
                seen = find_summaries(contact_labels, [Path(r) for r in args.observed_contact_reports])
            result["observed"]["contact"] = score_contact_cases(
                contact_labels, seen, targets=dict(design.targets), min_size_sd=design.min_size_sd
            )
    write_result(args.output, score_cases, result)
    write_benchmark_markdown(result, args.markdown)
    log.info(
        "false alarms %.3f (n=%d), top-1 %.3f (n=%d), both named %.3f (n=%d), none outside %.3f (n=%d), "
        "magnitude error %.3f, shrinkage %.3f",
        result["false_alarm"],
        result["n_null"],
        result["top1_big"],
        result["n_big"],
        result["both_named_big"],
        result["n_double_big"],
        result["none_recall_outside"],
        result["n_outside"],
        result["magnitude_rel_error_median"],
        result["shrinkage_median"],
    )
    return 0
