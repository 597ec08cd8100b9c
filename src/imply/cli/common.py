"""What every command group of the ``imply`` CLI shares: one-line user errors, argument types, output checks.

A user error (bad input, bad option, an output that would overwrite an input) is raised
as :class:`UserError` and printed by :func:`imply.cli.main` as one line with exit status
2, leaving no output file.
"""

from __future__ import annotations

import argparse
import json
import os
from collections.abc import Iterable
from pathlib import Path
from typing import Any

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


def config_from_json(cls, value: Any, option: str):
    """A :class:`imply.options.Config` from a JSON option's value, or a one-line error naming the option."""
    if value is not None and not isinstance(value, dict):
        raise UserError(f"{option}: expected a JSON object, not {type(value).__name__}")
    try:
        return cls.from_dict(value, option)
    except (TypeError, ValueError) as exc:
        raise UserError(one_line(exc)) from exc


class Parser(argparse.ArgumentParser):
    """argparse, with usage errors in one line like every other refusal (exit status 2)."""

    def error(self, message: str):
        self.exit(EXIT_USER_ERROR, f"{self.prog}: error: {one_line(message)} (see '{self.prog} --help')\n")


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


def add_scene_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", help="config.yaml to take the 'scene' section from")
    p.add_argument("--scene-json", type=json_arg, help="scene settings as JSON (overrides --config)")


def config_section(path: str, key: str) -> Any:
    """Section ``key`` of a config file named with --config, or a one-line error."""
    import yaml

    try:
        with open(path) as fh:
            cfg = yaml.safe_load(fh)
    except OSError as exc:
        raise UserError(f"--config {path}: {exc.strerror}") from exc
    except yaml.YAMLError as exc:
        raise UserError(f"--config {path}: not valid YAML: {exc}") from exc
    if cfg is not None and not isinstance(cfg, dict):
        raise UserError(f"--config {path}: expected a mapping of sections")
    return (cfg or {}).get(key)


def scene_from_args(args: argparse.Namespace, compile_model: bool = False):
    """The scene of --scene-json (or --config's ``scene``), checked; bad settings are a UserError."""
    from imply.config_check import ConfigError, check_scene

    cfg, where = None, "--scene-json"
    if getattr(args, "config", None):
        cfg, where = config_section(args.config, "scene"), f"--config {args.config}: scene"
    if getattr(args, "scene_json", None) is not None:
        cfg, where = args.scene_json, "--scene-json"
    try:
        return check_scene(cfg, compile_model=compile_model, where=where)
    except ConfigError as exc:
        raise UserError(str(exc)) from exc


def read_user_table(path, required, numeric, optional_numeric=()):
    """A user CSV/parquet table and its rows' lines (:func:`imply.input_files.read_table_lines`), or a one-line error."""
    from imply.input_files import InputError, read_table_lines

    try:
        return read_table_lines(path, required, numeric, optional_numeric)
    except InputError as exc:
        raise UserError(str(exc)) from exc
