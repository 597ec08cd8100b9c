"""The gap stage's diagnoses: many push logs in one process (``imply study gap diagnose-many``), and the closed loop
(``closed-loop``): the recommended next pushes run in the logs' worlds and diagnosed again."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from imply.cli.common import UserError, config_from_json, diagnose_request, output_dir
from imply.cli.gap_logs import check_shard, lab_subset

log = logging.getLogger("imply")


def cmd_diagnose_many(args: argparse.Namespace) -> int:
    import pandas as pd

    from imply.diagnose.run import run
    from imply.realworld.shards import shard_cases

    check_shard(args)
    out = output_dir(args.output)
    stems: dict[str, str] = {}
    pushlogs = [str(p) for path in args.pushlogs for p in logs_in(path)]
    if not pushlogs:
        raise UserError(f"no push logs in {', '.join(args.pushlogs)}")
    pushlogs = shard_cases(pushlogs, args.shard, args.shards)
    if not pushlogs:
        # more shards than logs: this one has none, and its folder says so by being empty
        out.mkdir(parents=True, exist_ok=True)
        log.info("shard %d of %d holds none of the logs", args.shard, args.shards)
        return 0
    # a benchmark world that settled none of a log's pushes leaves a log with no rows: nothing to diagnose, and its
    # scoring leaves it out too (imply.realworld.benchmark.measured)
    with_rows = []
    for path in pushlogs:
        if Path(path).suffix == ".csv" and pd.read_csv(path, nrows=1).empty:
            log.warning("%s passed by: no data rows (its world settled none of its pushes)", path)
        else:
            with_rows.append(path)
    pushlogs = with_rows
    if not pushlogs:
        return 0
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
    from imply.realworld.lab import draw_lab_cases
    from imply.sim import SceneConfig

    if args.lab_json is not None:
        if args.set is None:
            raise UserError("--lab-json needs --set (development or sealed)")
        design = lab_subset(args)
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
