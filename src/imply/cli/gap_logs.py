"""The gap stage's logs: the effect tables (``imply study gap tables``), the benchmarks' synthetic push logs and their sealed
labels (``generate``, ``lab-generate``, one shard each where asked) and the shards' labels joined (``merge-labels``)."""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

from imply.cli.common import (
    UserError,
    candidate_effects,
    config_from_json,
    diagnosis_options,
    load_table,
    output_dir,
    user_errors,
)

log = logging.getLogger("imply")


def check_shard(args: argparse.Namespace) -> None:
    """A one-line error unless ``--shard`` is below ``--shards``."""
    if args.shard >= args.shards:
        raise UserError(f"--shard {args.shard}: need 0 <= shard < --shards {args.shards}")


def benchmark_config(args: argparse.Namespace):
    from imply.realworld.cases import BenchmarkConfig

    return config_from_json(BenchmarkConfig, args.bench_json, "gap.benchmark")


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
    return benchmark_config(args)


def cmd_generate(args: argparse.Namespace) -> int:
    from imply.realworld.cases import write_benchmark_logs
    from imply.sim import SceneConfig

    check_shard(args)
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


def lab_config(args: argparse.Namespace):
    from imply.realworld.lab import LabBenchmarkConfig

    return config_from_json(LabBenchmarkConfig, args.lab_json, "gap.lab_benchmark")


def lab_subset(args: argparse.Namespace):
    """The lab benchmark's design (``--lab-json``) cut to the set ``--set`` names."""
    from imply.realworld.lab import LabBenchmarkConfig

    with user_errors(ValueError, TypeError, message="--lab-json: {error}"):
        return LabBenchmarkConfig.of_subset(args.lab_json, args.set)


def cmd_lab_generate(args: argparse.Namespace) -> int:
    from imply.realworld.lab import write_lab_set
    from imply.sim import SceneConfig

    check_shard(args)
    design = lab_subset(args)
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
