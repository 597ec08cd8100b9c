"""The ``imply`` command line: one module per top-level command group, each handler a thin wrapper.

Groups (modules of this package, each with ``register(subparsers)``): ``score``,
``table``, ``sim``, ``diagnose``, ``suite``, ``evaluate`` (what a user runs), and under
``imply study`` (:mod:`imply.cli.study`) the study's steps, one group per stage of the
workflow, which the workflow's rules call: ``section4``, ``clips``, ``encoder``,
``readout``, ``model``, ``section5``, ``gap``, ``pixel`` (the pixel-space model beyond the
paper), ``paper``. A handler parses its options, calls one library function and writes
its outputs; the logic lives in the library.

One convention for every command: outputs are ``-o/--output``; every command, option and
positional has help text, and a command without a description of its own shows its help;
every refusal, a usage error or a user error, is one line ``imply <command>: error: ...``
on standard error with exit status 2, and leaves no output file. A user error is a
:class:`~imply.cli.common.UserError`, raised by a handler or turned from the library's own
error types by :func:`~imply.cli.common.user_errors`; :func:`main` alone prints it.
Command groups share code only through :mod:`imply.cli.common`. Registering a group
imports nothing heavy: each command imports what it needs when it runs, so ``imply score``
never loads torch or matplotlib.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import signal
import sys
from typing import Any

import imply
from imply.cli.common import EXIT_INTERRUPTED, EXIT_USER_ERROR, Parser, UserError, one_line

GROUPS: list[str] = ["score", "table", "sim", "diagnose", "suite", "evaluate", "study"]


DESCRIPTION = (
    "Vet world-model rollouts against physics, and diagnose the gap between a push simulator and a robot. "
    "What you run: 'imply score' (a rollouts file's anchored disagreement), 'imply evaluate' (a world model on "
    "the frozen suite), 'imply diagnose' (a robot's push log against the push table), 'imply sim' (pushes "
    "simulated on the built-in scene or your MJCF), 'imply table' and 'imply suite' (what those read). 'imply "
    "study' holds the study's workflow steps, which 'snakemake --cores 2' runs. 'imply COMMAND --help' says what "
    "each reads and writes."
)


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="imply", description=DESCRIPTION)
    parser.add_argument("--log", help="also write the log to this file")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    parser.add_argument("--version", action="version", version=f"imply {imply.__version__}")
    sub = parser.add_subparsers(dest="group", required=True, metavar="COMMAND")
    for name in GROUPS:
        importlib.import_module(f"imply.cli.{name}").register(sub)
    _describe(parser)
    return parser


def _describe(parser: argparse.ArgumentParser) -> None:
    """Give every command without a description of its own its help as one, and every group's commands the
    metavar COMMAND (so a usage error names what is missing in words)."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            action.metavar = action.metavar or "COMMAND"
            helps = {choice.dest: choice.help for choice in action._choices_actions}
            for name, sub in action.choices.items():
                if not sub.description and helps.get(name):
                    sub.description = helps[name][0].upper() + helps[name][1:] + "."
                _describe(sub)


def command_name(args: argparse.Namespace) -> str:
    """The words of the command ``args`` were parsed for ('study gap diagnose-many'): each group's chosen
    subcommand sits in the namespace under ``<group>_command``."""
    words = [args.group]
    while (word := getattr(args, f"{words[-1]}_command", None)) is not None:
        words.append(word)
    return " ".join(words)


def _refuse_study_step_at_the_top(argv: list[str]) -> None:
    """A study step asked for without ``study`` (as the command lines before ``imply study`` read) is refused in
    one line that gives the command to run instead."""
    from imply.cli.study import STUDY_GROUPS

    words = [w for i, w in enumerate(argv) if not w.startswith("-") and (i == 0 or argv[i - 1] != "--log")]
    if words and words[0] in STUDY_GROUPS:
        print(
            f"imply: error: '{words[0]}' is a step of the study: run 'imply study {words[0]} ...' "
            "(see 'imply study --help')",
            file=sys.stderr,
        )
        raise SystemExit(EXIT_USER_ERROR)


def _terminate(signum: int, frame: Any) -> None:
    # a terminated job unwinds like Ctrl-C, so atomic writers remove their temporary files
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    from imply.io import setup_logging

    parser = build_parser()
    _refuse_study_step_at_the_top(sys.argv[1:] if argv is None else argv)
    args = parser.parse_args(argv)
    setup_logging(args.log, logging.DEBUG if args.verbose else logging.INFO)
    if argv is None and signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        # only as the console script: a caller's own process keeps its signal handling
        signal.signal(signal.SIGTERM, _terminate)
    import numpy as np

    np.seterr(all="ignore")
    name = command_name(args)
    prefix = f"imply {name}: error:"
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"{prefix} {one_line(exc)}", file=sys.stderr)
    except OSError as exc:
        # files the user named: unreadable, unwritable, a folder where a file belongs
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"{prefix} {one_line(where + (exc.strerror or str(exc)))}", file=sys.stderr)
    except ImportError as exc:
        from imply.extras import missing_extra

        if (message := missing_extra(exc)) is None:
            raise
        print(f"{prefix} {message}", file=sys.stderr)
    except MemoryError:
        print(f"{prefix} out of memory: the input or the options need more memory than is available", file=sys.stderr)
    except KeyboardInterrupt:
        print(f"imply {name}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_USER_ERROR
