"""The ``imply`` command line: one entry point per workflow step and per user task.

Core commands live here; each study area adds its own from a module listed in
``COMMAND_MODULES`` that exposes ``register(subparsers)``. A user error (bad input,
bad option) prints one line and exits with status 2, leaving no output file.
"""

from __future__ import annotations

import argparse
import importlib
import json
import logging
import sys
from pathlib import Path
from typing import Any

import numpy as np

# modules that add subcommands; each has register(subparsers)
COMMAND_MODULES: list[str] = [
    "imply.commands_core",
    "imply.commands_section4",
    "imply.commands_gap",
    "imply.commands_clips",
    "imply.commands_model",
]


class UserError(Exception):
    """Bad input or options: reported in one line, exit status 2."""


def json_arg(text: str) -> Any:
    """Parse a JSON option value (how workflow rules pass their config subset)."""
    try:
        return json.loads(text)
    except json.JSONDecodeError as exc:
        raise argparse.ArgumentTypeError(f"not valid JSON: {exc}") from exc


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="imply", description=__doc__.splitlines()[0])
    parser.add_argument("--log", help="also write the log to this file")
    parser.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    from imply.io import setup_logging

    parser = build_parser()
    args = parser.parse_args(argv)
    setup_logging(args.log, logging.DEBUG if args.verbose else logging.INFO)
    np.seterr(all="ignore")
    try:
        return int(args.func(args) or 0)
    except UserError as exc:
        print(f"imply {args.command}: error: {exc}", file=sys.stderr)
        return 2


def existing_file(text: str) -> Path:
    path = Path(text)
    if not path.is_file():
        raise argparse.ArgumentTypeError(f"{text} does not exist")
    return path


if __name__ == "__main__":
    sys.exit(main())
