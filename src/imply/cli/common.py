"""What every command group of the ``imply`` CLI shares: one-line user errors, argument types, output checks,
and the options of a run of diagnoses.

A user error (bad input, bad option, an output that would overwrite an input) is raised
as :class:`UserError`, directly or by :func:`user_errors` from the library's own error
types, and printed by :func:`imply.cli.main` as one line with exit status 2, leaving no
output file. This is the only module the command groups import from each other:
``imply diagnose`` and ``imply study gap diagnose-many`` declare their shared options with
:func:`add_diagnose_options` and check them once into a
:class:`imply.diagnose.run.DiagnoseRequest` with :func:`diagnose_request`.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from imply.diagnose.analysis import DiagnosisConfig
    from imply.diagnose.physics.candidates import Candidate
    from imply.diagnose.physics.effect_tables import CoarseGrid
    from imply.diagnose.run import DiagnoseRequest
    from imply.table import PushTable

EXIT_USER_ERROR = 2
EXIT_INTERRUPTED = 130


class UserError(Exception):
    """Bad input or options: reported in one line, exit status 2."""


@contextlib.contextmanager
def user_errors(*kinds: type[Exception], message: str = "{error}") -> Iterator[None]:
    """Raise the library errors ``kinds`` met inside as a :class:`UserError`: ``message`` with ``{error}``
    replaced by the error's text (say which option or file it is about)."""
    try:
        yield
    except kinds as exc:
        raise UserError(message.replace("{error}", str(exc))) from exc


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


# -- a run of diagnoses: imply diagnose, imply study gap diagnose-many ------------------------

DEFAULT_TABLE = "results/table/table.npz"


def add_diagnose_options(p: argparse.ArgumentParser) -> None:
    """The options of a run of diagnoses (besides the push logs and ``-o``), one declaration for every command."""
    p.add_argument(
        "--force",
        action="store_true",
        help="write into a non-empty report folder: replace the files an earlier report wrote there, keep the rest",
    )
    p.add_argument("--table", default=DEFAULT_TABLE, help="baseline push table (default %(default)s)")
    p.add_argument("--cache-dir", help="effect-table cache (default $IMPLY_CACHE or ~/.cache/imply)")
    p.add_argument("--effects", help="comma-separated candidate effects (default: the whole library)")
    p.add_argument(
        "--effect-grid-json", type=json_arg, help="coarse grid of the effect tables (config gap.effect_grid)"
    )
    p.add_argument("--options-json", type=json_arg, help="diagnostic settings (config gap.diagnose)")
    p.add_argument(
        "--noise-sd", type=positive_float, help="log-displacement noise sd, used when the log has no replicates"
    )
    p.add_argument(
        "--ignore-measured", action="store_true", help="fit mass and friction even where the log has measured values"
    )
    p.add_argument("--threads", type=int_range(0), default=0, help="simulation threads for building effect tables")
    p.add_argument(
        "--no-plots", action="store_true", help="write no figures (report.md without them): for many logs read as data"
    )


def cache_dir(arg: str | None) -> Path:
    """The effect-table cache: ``--cache-dir``, else ``$IMPLY_CACHE``, else ``~/.cache/imply``."""
    if arg:
        return Path(arg)
    return Path(os.environ.get("IMPLY_CACHE") or Path.home() / ".cache" / "imply")


def load_table(path: str) -> PushTable:
    """The baseline push table of ``--table`` (with how to build the default one where it is missing)."""
    hint = "build it with 'snakemake --cores 2 results/table/table.npz'" if path == DEFAULT_TABLE else ""
    return load_push_table(path, "--table", hint)


def candidate_effects(arg: str | None) -> list[Candidate]:
    """The candidates of ``--effects`` (all of the library when absent)."""
    from imply.diagnose.physics import candidates

    with user_errors(ValueError, message="--effects: {error}"):
        return candidates.get(None if not arg else [x.strip() for x in arg.split(",") if x.strip()])


def diagnosis_options(
    options_json: Any, grid_json: Any, *, noise_sd: float | None = None, ignore_measured: bool = False
) -> tuple[DiagnosisConfig, CoarseGrid]:
    """Diagnostic settings and effect-table grid from their JSON options (and the flags that override them)."""
    from imply.diagnose.analysis import DiagnosisConfig
    from imply.diagnose.physics.effect_tables import CoarseGrid

    opts = config_from_json(DiagnosisConfig, options_json, "--options-json")
    grid = config_from_json(CoarseGrid, grid_json, "--effect-grid-json")
    if noise_sd is not None:
        opts = opts.replace(noise_sd=noise_sd)
    if ignore_measured:
        opts = opts.replace(use_measured=False)
    return opts, grid


def diagnose_request(args: argparse.Namespace, reports: list[tuple]) -> DiagnoseRequest:
    """The options of :func:`add_diagnose_options` and each (push log, report folder[, reference session or
    None]), checked once before any work: the report folders, the table, every push log and reference against it
    (a reference must push the log's boxes), the settings, the candidates."""
    from imply.diagnose.inference.sessions import check_pair
    from imply.diagnose.run import DiagnoseRequest, Report, check_report_folder, read_checked_pushlog, user_scene
    from imply.input_files import InputError
    from imply.io import OutputError

    folders = []
    for pushlog, folder, *ref in reports:
        out = output_dir(folder)
        with user_errors(OutputError, message="-o {error}"):
            check_report_folder(out, args.force, [pushlog, args.table, *(r for r in ref if r)])
        folders.append(out)
    table = load_table(args.table)
    scene = None
    if getattr(args, "model", None):
        with user_errors(ValueError, message="--model {error}"):
            scene = user_scene(args.model)
    with user_errors(InputError):
        logs = [read_checked_pushlog(r[0], table, getattr(args, "track", None)) for r in reports]
        # a reference session reads its own track and probes from the files beside it
        refs = [read_checked_pushlog(r[2], table) if len(r) > 2 and r[2] else None for r in reports]
        for log_, ref in zip(logs, refs, strict=True):
            if ref is not None:
                check_pair(log_, ref)
    opts, grid = diagnosis_options(
        args.options_json, args.effect_grid_json, noise_sd=args.noise_sd, ignore_measured=args.ignore_measured
    )
    if getattr(args, "refit", False):
        opts = opts.replace(simulator_refit=True)
    return DiagnoseRequest(
        table=table,
        candidates=tuple(candidate_effects(args.effects)),
        options=opts,
        grid=grid,
        cache_dir=cache_dir(args.cache_dir),
        threads=args.threads,
        scene=scene,
        force=args.force,
        plots=not args.no_plots,
        reports=tuple(
            Report(pushlog=log, folder=out, reference=ref) for log, out, ref in zip(logs, folders, refs, strict=True)
        ),
    )
