"""The gap stage's scores: which lab logs can be told apart from their contact (``imply study gap separability``), a lab
set's diagnoses scored with and without probes (``lab-score``), and the benchmarks scored against their sealed labels
(``benchmark``)."""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

from imply.cli.common import (
    UserError,
    config_from_json,
    load_table,
    user_errors,
)
from imply.cli.gap_logs import benchmark_config, lab_config

log = logging.getLogger("imply")


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

    design = lab_config(args)
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
    from imply.realworld.benchmark import CONTACT_SINGLE, find_summaries, measured, shrink_sizes
    from imply.realworld.lab_score import score_lab, write_lab_score

    design = lab_config(args)
    with user_errors(FileNotFoundError, message="--labels: {error}"):
        with open(args.labels) as fh:
            labels = measured(json.load(fh))
    summaries = {}
    tiers = (
        ("no_probes", [args.reports_no_probes]),
        ("probes", [args.reports_probes]),
        ("reference", args.reports_reference),
    )
    for variant, folders in tiers:
        if not folders:
            continue
        with user_errors(FileNotFoundError, message=f"--reports-{variant.replace('_', '-')}: {{error}}"):
            summaries[variant] = find_summaries(labels, [Path(f) for f in folders])
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
    from imply.realworld.benchmark import find_summaries, measured, score_cases, visible_sizes
    from imply.realworld.benchmark_report import write_benchmark_markdown

    table = load_table(args.table)
    config = benchmark_config(args)
    with open(args.sealed) as fh:
        labels = measured(json.load(fh))
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
            contact_labels = measured(json.load(fh))
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
