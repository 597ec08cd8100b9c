"""``imply evaluate``: score world models' rollouts on a frozen suite, in one report.

``imply evaluate --model MODULE:FACTORY [--model ...] --suite DIR -o REPORT`` runs models
in this process; ``--rollouts FILE`` (repeatable) scores rollouts generated elsewhere; the
two may be mixed. The report folder is written only when every model has been scored.
"""

from __future__ import annotations

import argparse
import logging
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
        "writes one report folder comparing the models: report.md, results.json (every number), per_object.csv, and "
        "the figures slides.png/.pdf, scores.png/.pdf and, where a model has a selection, selection.png/.pdf; with "
        "--command also REPORT.package, REPORT.videos and REPORT.command.log beside it. A model is MODULE:FACTORY "
        "(an importable module or a .py file) whose factory returns an object with kind and rollout(request); "
        "see the tutorial docs/tutorials/evaluate.md.",
    )
    p.add_argument(
        "--model", action="append", default=[], metavar="MODULE:FACTORY", help="a model to run in process (repeatable)"
    )
    p.add_argument(
        "--rollouts",
        action="append",
        default=[],
        metavar="FILE",
        help="rollouts generated elsewhere (.npz, or .csv of displacements; repeatable)",
    )
    p.add_argument(
        "--videos",
        action="append",
        default=[],
        metavar="FOLDER",
        help="a folder of generated videos named as 'imply suite export' says (MP4 or PNG folders; "
        "repeatable; the model's name is the folder's)",
    )
    p.add_argument(
        "--check",
        action="store_true",
        help="only check the --videos folders (missing, extra, duplicated, undecodable files, mixed frame "
        "rates, no frame after the context); exit 2 on any problem",
    )
    p.add_argument(
        "--command",
        metavar="'CMD {package} {cases} {out}'",
        help="a generation command run in its own environment: the suite is exported beside the report "
        "(REPORT.package), the command writes the pending cases' videos into REPORT.videos, which is "
        "then checked and scored; an interrupted run asks only for the cases still missing",
    )
    p.add_argument("--name", default="command", help="the --command model's name in the report (default %(default)s)")
    p.add_argument("--suite", required=True, help="suite folder (results/suite from the workflow)")
    p.add_argument("-o", "--output", help="report folder to write (needed unless --check)")
    p.add_argument("--force", action="store_true", help="replace a report written there before")
    p.add_argument(
        "--conditions",
        default=",".join(default_of(EvaluateConfig, "conditions")),
        help="calibration conditions to ask, comma-separated (default %(default)s)",
    )
    p.add_argument(
        "--samples",
        type=int_range(1),
        default=default_of(EvaluateConfig, "samples"),
        help="sample sets per object for a stochastic model (default %(default)d)",
    )
    p.add_argument(
        "--bootstrap",
        type=int_range(0),
        default=default_of(EvaluateConfig, "bootstrap"),
        help="bootstrap resamples for the 95%% intervals (default %(default)d)",
    )
    p.add_argument(
        "--seed",
        type=int_range(0),
        default=default_of(EvaluateConfig, "seed"),
        help="seed of the bootstrap and the random selection rule (default %(default)d)",
    )
    p.add_argument(
        "--static-limit",
        type=positive_float,
        default=default_of(EvaluateConfig, "static_limit"),
        help="a set whose every slide is below this many metres is flagged static (default %(default)g)",
    )
    p.add_argument(
        "--cache",
        help="folder for finished batches, so an interrupted run resumes "
        "(default: REPORT.cache beside the report; removed once the report is written)",
    )
    p.add_argument("--no-cache", action="store_true", help="keep no batches on disk")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=cmd_evaluate)


def cmd_evaluate(args: argparse.Namespace) -> int:
    from imply.evaluate.config import EvaluateConfig, parse_conditions
    from imply.evaluate.interface import ModelError
    from imply.evaluate.request import EvaluateRequest, run_request
    from imply.evaluate.rollouts_file import RolloutsFileError
    from imply.evaluate.suite import SuiteError
    from imply.evaluate.video_package import CommandError, VideoFolderError
    from imply.io import OutputError
    from imply.table import OutOfRangeError

    out = output_dir(args.output) if args.output else None
    with user_errors(ValueError, message="--conditions: {error}"):
        settings = EvaluateConfig(
            conditions=parse_conditions(args.conditions),
            samples=args.samples,
            bootstrap=args.bootstrap,
            seed=args.seed,
            static_limit=args.static_limit,
        )
    with user_errors(ValueError):
        request = EvaluateRequest(
            suite=Path(args.suite),
            output=out,
            settings=settings,
            models=tuple(args.model),
            rollouts=tuple(Path(f) for f in args.rollouts),
            videos=tuple(Path(f) for f in args.videos),
            command=args.command,
            name=args.name,
            check=args.check,
            force=args.force,
            cache=Path(args.cache) if args.cache else None,
            keep_cache=not args.no_cache,
            progress=not args.no_progress,
        )
    try:
        with user_errors(SuiteError, message="--suite: {error}"):
            evaluations = run_request(request)
    except VideoFolderError as exc:
        for line in exc.problems[:-1]:
            print(f"imply evaluate: error: {line}", file=sys.stderr)
        raise UserError(exc.problems[-1]) from None
    except CommandError as exc:
        first, *rest = str(exc).splitlines()
        for line in rest:  # the command's own last lines, as it printed them
            print(line, file=sys.stderr)
        raise UserError(first) from None
    except (ModelError, RolloutsFileError, OutOfRangeError, OutputError, ValueError) as exc:
        raise UserError(str(exc)) from exc
    for ev in evaluations:
        far = sum(d.unphysical for d in ev.degenerate)
        if far:
            print(
                f"warning: {ev.model}: {far} rollout(s) read a slide more than ten times the suite's longest real "
                "one (a units slip?); flagged in the report",
                file=sys.stderr,
            )
        own = ev.condition("own") or ev.conditions[0]
        log.info(
            "%s (%s, %s readout): %s tracking r %s, log error %s",
            ev.model,
            ev.kind,
            ev.readout.name,
            own.condition,
            own.track.format(".2f"),
            own.error.format(".3f"),
        )
    if evaluations:
        log.info("report -> %s", out)
    return 0
