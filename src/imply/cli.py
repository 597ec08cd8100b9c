"""The ``imply`` command line: one entry point per workflow step and per user task.

Core commands live here; each study area adds its own from a module listed in
``COMMAND_MODULES`` that exposes ``register(subparsers)``. A user error (bad input,
bad option, an output that would overwrite an input) prints one line and exits with
status 2, leaving no output file. Registering a subcommand imports nothing heavy:
each command imports what it needs when it runs, so ``imply score`` never loads
torch or matplotlib.
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import os
import signal
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import Any

# modules that add subcommands; each has register(subparsers)
COMMAND_MODULES: list[str] = [
    "imply.commands_core",
    "imply.commands_section4",
    "imply.commands_gap",
    "imply.commands_clips",
    "imply.commands_model",
]

EXIT_USER_ERROR = 2
EXIT_INTERRUPTED = 130


class UserError(Exception):
    """Bad input or options: reported in one line, exit status 2."""


def one_line(text: object) -> str:
    """A message on one line: library errors (XML, CSV parsers) often span several."""
    return " ".join(str(text).split())


def json_arg(text: str) -> Any:
    """Parse a JSON option value (how workflow rules pass their config subset)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not valid JSON: {exc}") from exc


def int_range(lo: int, hi: int | None = None):
    """An argparse type: an integer in [lo, hi]."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
        if value < lo or (hi is not None and value > hi):
            bound = f"between {lo} and {hi}" if hi is not None else f"at least {lo}"
            raise argparse.ArgumentTypeError(f"{value} is out of range (must be {bound})")
        return value

    return parse


def positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (value > 0 and value < float("inf")):
        raise argparse.ArgumentTypeError(f"{text} must be a positive number")
    return value


class Parser(argparse.ArgumentParser):
    """argparse, with usage errors in one line like every other refusal (exit status 2)."""

    def error(self, message: str):
        self.exit(EXIT_USER_ERROR, f"{self.prog}: error: {one_line(message)} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(prog="imply", description=__doc__.splitlines()[0])
    parser.add_argument("--log", help="also write the log to this file")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def _terminate(signum: int, frame: Any) -> None:
    # a terminated job unwinds like Ctrl-C, so atomic writers remove their temporary files
    raise KeyboardInterrupt


def main(argv: list[str] | None = None) -> int:
    from imply.io import setup_logging

    parser = build_parser()
    args = parser.parse_args(argv)
    setup_logging(args.log, logging.DEBUG if args.verbose else logging.INFO)
    if argv is None and signal.getsignal(signal.SIGTERM) is signal.SIG_DFL:
        # only as the console script: a caller's own process keeps its signal handling
        signal.signal(signal.SIGTERM, _terminate)
    import numpy as np

    np.seterr(all="ignore")
    name = " ".join(x for x in (args.command, getattr(args, f"{args.command}_command", None)) if x)
    prefix = f"imply {name}: error:"
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"{prefix} {one_line(exc)}", file=sys.stderr)
    except OSError as exc:
        # files the user named: unreadable, unwritable, a folder where a file belongs
        where = f"{exc.filename}: " if exc.filename else ""
        print(f"{prefix} {one_line(where + (exc.strerror or str(exc)))}", file=sys.stderr)
    except MemoryError:
        print(f"{prefix} out of memory: the input or the options need more memory than is available", file=sys.stderr)
    except KeyboardInterrupt:
        print(f"imply {name}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    return EXIT_USER_ERROR


def existing_file(text: str) -> Path:
    path = Path(text)
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text} does not exist")
    return path


def _same_path(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _check_parent(path: Path, option: str, folder: Path | None = None) -> None:
    """Refuse an output whose folder (``folder``, default the path's own) cannot exist or be written."""
    parent = (folder if folder is not None else path.parent).absolute()
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise UserError(f"{option} {path}: {parent} is a file, not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise UserError(f"{option} {path}: cannot write in {parent} (permission denied)")


def output_file(path: str | os.PathLike, inputs: Iterable[str | os.PathLike | None] = (), option: str = "-o") -> Path:
    """Check an output file path before any work: not a folder, writable, not an input.

    Refusing early means a bad path costs nothing and leaves nothing behind; an
    output that names an input would replace the user's data with the result.
    """
    out = Path(path)
    if out.is_dir():
        raise UserError(f"{option} {out} is a folder; give a file name")
    for src in inputs:
        if src is not None and (_same_path(out, Path(src)) or out.absolute() == Path(src).absolute()):
            raise UserError(f"{option} {out} is also an input; write the output to another file")
    _check_parent(out, option)
    return out


def output_dir(path: str | os.PathLike, option: str = "-o") -> Path:
    """Check an output folder path before any work: not a file, writable."""
    out = Path(path)
    if out.exists() and not out.is_dir():
        raise UserError(f"{option} {out} is a file; give a folder for the report")
    _check_parent(out, option, folder=out)
    return out


def load_push_table(path: str | os.PathLike, option: str = "--table", hint: str = ""):
    """A :class:`imply.table.PushTable` from a user-named file, or a one-line error."""
    import zipfile

    from imply.table import PushTable, TableError

    path = Path(path)
    suffix = f" ({hint})" if hint else ""
    if not path.is_file():
        what = "is a folder" if path.is_dir() else "does not exist"
        raise UserError(f"{option}: table file {path} {what}{suffix}")
    if not zipfile.is_zipfile(path):
        raise UserError(f"{option}: {path} is not a push table (expected the .npz file 'imply table build' writes)")
    try:
        return PushTable.load(path)
    except TableError as exc:
        raise UserError(f"{option}: {exc}{suffix}") from exc


if __name__ == "__main__":
    # run as `python -m imply.cli`: use the package's module, whose UserError the commands raise
    from imply.cli import main as package_main

    sys.exit(package_main())
