"""``imply evaluate``: score world models' rollouts on a frozen suite, in one report.

``imply evaluate --model MODULE:FACTORY [--model ...] --suite DIR -o REPORT`` runs models
in this process; ``--rollouts FILE`` (repeatable) scores rollouts generated elsewhere; the
two may be mixed. The report folder is written only when every model has been scored.
"""

from __future__ import annotations

import argparse
import logging
import shutil
import sys
from pathlib import Path

from imply.cli.common import UserError, int_range, output_dir, positive_float, user_errors

log = logging.getLogger("imply")


def register(sub: argparse._SubParsersAction) -> None:
    from imply.evaluate.config import EvaluateConfig
    from imply.options import default_of

    p = sub.add_parser(
        "evaluate",
        help="score world models on a suite: tracking, error, self and anchored disagreement, selection",
        description="Asks each model for its rollouts of the suite's held-out pushes (own calibration, another "
        "object's, none), reads them with a readout fitted on the suite's real clips (never on the rollouts), and "
        "writes one report comparing the models: results.json, report.md, figures. A model is MODULE:FACTORY "
        "(an importable module or a .py file) whose factory returns an object with kind and rollout(request); "
        "see the tutorial docs/tutorials/evaluate.md.",
    )
    p.add_argument("--model", action="append", default=[], metavar="MODULE:FACTORY",
                   help="a model to run in process (repeatable)")  # fmt: skip
    p.add_argument("--rollouts", action="append", default=[], metavar="FILE",
                   help="rollouts generated elsewhere (.npz, or .csv of displacements; repeatable)")  # fmt: skip
    p.add_argument("--videos", action="append", default=[], metavar="FOLDER",
                   help="a folder of generated videos named as 'imply suite export' says (MP4 or PNG folders; "
                        "repeatable; the model's name is the folder's)")  # fmt: skip
    p.add_argument("--check", action="store_true",
                   help="only check the --videos folders (missing, extra, duplicated, undecodable files, mixed frame "
                        "rates, no frame after the context); exit 2 on any problem")  # fmt: skip
    p.add_argument("--command", metavar="'CMD {package} {cases} {out}'",
                   help="a generation command run in its own environment: the suite is exported beside the report "
                        "(REPORT.package), the command writes the pending cases' videos into REPORT.videos, which is "
                        "then checked and scored; an interrupted run asks only for the cases still missing")  # fmt: skip
    p.add_argument("--name", default="command", help="the --command model's name in the report (default %(default)s)")
    p.add_argument("--suite", required=True, help="suite folder (results/suite from the workflow)")
    p.add_argument("-o", "--output", help="report folder to write (needed unless --check)")
    p.add_argument("--force", action="store_true", help="replace a report written there before")
    p.add_argument("--conditions", default=",".join(default_of(EvaluateConfig, "conditions")),
                   help="calibration conditions to ask, comma-separated (default %(default)s)")  # fmt: skip
    p.add_argument("--samples", type=int_range(1), default=default_of(EvaluateConfig, "samples"),
                   help="sample sets per object for a stochastic model (default %(default)d)")  # fmt: skip
    p.add_argument("--bootstrap", type=int_range(0), default=default_of(EvaluateConfig, "bootstrap"),
                   help="bootstrap resamples for the 95%% intervals (default %(default)d)")  # fmt: skip
    p.add_argument("--seed", type=int_range(0), default=default_of(EvaluateConfig, "seed"),
                   help="seed of the bootstrap and the random selection rule (default %(default)d)")  # fmt: skip
    p.add_argument("--static-limit", type=positive_float, default=default_of(EvaluateConfig, "static_limit"),
                   help="a set whose every slide is below this many metres is flagged static (default %(default)g)")  # fmt: skip
    p.add_argument("--cache", help="folder for finished batches, so an interrupted run resumes "
                   "(default: REPORT.cache beside the report; removed once the report is written)")  # fmt: skip
    p.add_argument("--no-cache", action="store_true", help="keep no batches on disk")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_evaluate)


def _checked_videos(folders: list[str], suite, conditions: tuple[str, ...]) -> list:
    """Every --videos folder checked and read as rollouts; every problem of every folder is printed (one line per
    kind) before the command stops with status 2."""
    from imply.evaluate.video_package import VideoFolderError, read_videos

    out, problems = [], []
    for folder in folders:
        try:
            out.append(read_videos(folder, suite, conditions))
        except VideoFolderError as exc:
            problems += exc.problems
    if problems:
        for line in problems[:-1]:
            print(f"error: {line}", file=sys.stderr)
        raise UserError(problems[-1] + " (nothing scored)")
    return out


def _generate(args: argparse.Namespace, suite, conditions: tuple[str, ...], out: Path) -> Path:
    """Export the suite beside the report (once), run the --command for the cases not generated yet, and return
    the videos folder (named by --name)."""
    from imply.evaluate.video_package import CommandError, export_package, read_manifest, run_command

    package = out.with_name(out.name + ".package")
    videos = out.with_name(out.name + ".videos") / args.name
    made = None
    if package.exists():
        with user_errors(ValueError):
            made = read_manifest(package)
    if made is None or made["suite"] != suite.checksum or made["conditions"] != list(conditions):
        if package.exists():
            shutil.rmtree(package)
        with user_errors(ValueError):
            export_package(suite, package, conditions=conditions)
    try:
        n = run_command(args.command, package=package, videos=videos, log_path=out.with_name(out.name + ".command.log"))
    except CommandError as exc:
        first, *rest = str(exc).splitlines()
        for line in rest:  # the command's own last lines, as it printed them
            print(line, file=sys.stderr)
        raise UserError(first) from None
    log.info("--command generated %d case(s) -> %s", n, videos)
    return videos


def cmd_evaluate(args: argparse.Namespace) -> int:
    from imply.evaluate.config import EvaluateConfig
    from imply.evaluate.harness import evaluate
    from imply.evaluate.interface import ModelError
    from imply.evaluate.report import check_report_folder, write_report
    from imply.evaluate.rollouts_file import RolloutsFileError
    from imply.evaluate.suite import SuiteError, load_suite
    from imply.io import OutputError
    from imply.table import OutOfRangeError

    if not args.model and not args.rollouts and not args.videos and not args.command:
        raise UserError("give at least one --model MODULE:FACTORY, --rollouts FILE, --videos FOLDER or --command")
    if args.check and not args.videos:
        raise UserError("--check checks --videos folders: give at least one")
    if not args.check and not args.output:
        raise UserError("give the report folder: -o REPORT")
    out = output_dir(args.output) if args.output else None
    conditions = tuple(c.strip() for c in args.conditions.split(",") if c.strip())
    with user_errors(ValueError, message="--conditions: {error}"):
        settings = EvaluateConfig(
            conditions=conditions, samples=args.samples, bootstrap=args.bootstrap, seed=args.seed,
            static_limit=args.static_limit,
        )  # fmt: skip
    inputs = [Path(f) for f in args.rollouts + args.videos]
    if not args.check:
        with user_errors(OutputError):
            check_report_folder(out, force=args.force, inputs=inputs)
    with user_errors(SuiteError, message="--suite: {error}"):
        suite = load_suite(args.suite)
    if args.command:
        if out is None:
            raise UserError("--command needs the report folder: -o REPORT")
        args.videos = [*args.videos, str(_generate(args, suite, settings.conditions, out))]
    videos = _checked_videos(args.videos, suite, settings.conditions)  # always before any scoring
    if args.check:
        log.info("%d folder(s) of videos checked: nothing wrong", len(videos))
        return 0
    cache = None if args.no_cache else Path(args.cache) if args.cache else out.with_name(out.name + ".cache")
    with user_errors(ModelError, RolloutsFileError, SuiteError, OutOfRangeError):
        evaluations = evaluate(
            args.model, suite=suite, rollouts=[*args.rollouts, *videos], settings=settings, cache_dir=cache,
            progress=not args.no_progress,
        )  # fmt: skip
    with user_errors(OutputError, ValueError):
        write_report(evaluations, out, force=args.force, inputs=inputs)
    if cache is not None and args.cache is None and cache.exists():
        shutil.rmtree(cache, ignore_errors=True)
    for ev in evaluations:
        far = sum(d.unphysical for d in ev.degenerate)
        if far:
            print(f"warning: {ev.model}: {far} rollout(s) read a slide more than ten times the suite's longest real "
                  "one (a units slip?); flagged in the report", file=sys.stderr)  # fmt: skip
        own = ev.condition("own") or ev.conditions[0]
        log.info("%s (%s, %s readout): %s tracking r %s, log error %s", ev.model, ev.kind, ev.readout.name,
                 own.condition, own.track.format(".2f"), own.error.format(".3f"))  # fmt: skip
    log.info("report -> %s", out)
    return 0
