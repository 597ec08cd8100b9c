"""Core subcommands: ``imply score``, ``imply table build``, ``imply sim export-xml|pushes``.

Heavy modules (MuJoCo, pandas, the table's interpolation) are imported inside the
commands that use them, so that starting ``imply`` stays cheap for every command.
"""

from __future__ import annotations

import argparse
import logging
import os
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from imply.cli import UserError, int_range, json_arg, load_push_table, output_file, positive_float
from imply.score import DEFAULT_FLOOR, DEFAULT_GRID

if TYPE_CHECKING:
    from imply.score import Scorer
    from imply.sim import SceneConfig
    from imply.table import PushTable

log = logging.getLogger("imply")

SCORE_COLUMNS = [
    "object_id", "n_rollouts", "self_disagreement", "anchored_disagreement",
    "mass_hat", "friction_hat", "anchored_mass_hat", "anchored_friction_hat",
]  # fmt: skip
ROLES = ("calibration", "rollout")
# the search grid's cached rows take 24 grid^2 bytes per distinct speed, and a block of
# the exhaustive search 8 grid^2 bytes per set in it: 1001 keeps both in the hundreds of MB
MAX_GRID = 1001


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "score",
        help="score rollout sets: self and anchored disagreement per object",
        description="Reads ROLLOUTS (object_id,role,speed,displacement; role calibration|rollout; one row per "
        "object, role and speed) and writes one row of scores per object.",
    )
    p.add_argument("rollouts", help="CSV with object_id,role,speed,displacement (role: calibration|rollout; metres)")
    p.add_argument("--table", required=True, help="push table (.npz) from 'imply table build'")
    p.add_argument("-o", "--output", required=True, help="scores CSV to write (not one of the inputs)")
    p.add_argument("--floor", type=positive_float, default=DEFAULT_FLOOR,
                   help="readout floor in metres (default %(default)g)")  # fmt: skip
    p.add_argument("--grid", type=int_range(2, MAX_GRID), default=DEFAULT_GRID,
                   help=f"search grid points per axis, 2 to {MAX_GRID} (default %(default)d)")  # fmt: skip
    p.add_argument("--threads", type=int_range(0), default=0, help="scoring threads (0: all CPUs)")
    p.set_defaults(func=cmd_score)

    t = sub.add_parser("table", help="build the push table f(v, m, mu) -> log d")
    tsub = t.add_subparsers(dest="table_command", required=True)
    tb = tsub.add_parser("build", help="simulate every cell and write the table")
    _add_scene_options(tb)
    tb.add_argument("--grid-json", type=json_arg, help="table axes as JSON (config key 'table')")
    tb.add_argument("-o", "--output", required=True)
    tb.add_argument("--threads", type=int_range(0), default=0, help="simulation threads (0: all CPUs)")
    tb.add_argument(
        "--check-json",
        type=json_arg,
        help="how to measure the table's numerical error, recorded in its metadata (config key 'table_check': "
        'cells, seed, reference_substeps; default {"cells": 200}; {"cells": 0} skips it)',
    )
    tb.set_defaults(func=cmd_table_build)
    tc = tsub.add_parser(
        "check",
        help="measure a table's numerical error against a much finer reference",
        description=(
            "Compares the table's log d at sampled grid nodes (the 8 corners of the range, then random ones) "
            "with the same scene stepped uniformly at a much finer step on a separate code path, and prints "
            "max and RMS of |delta log d| and the reference's own error estimate."
        ),
    )
    tc.add_argument("table", help="push table (.npz)")
    tc.add_argument("--cells", type=int_range(1), default=200, help="grid nodes to compare (default %(default)d)")
    tc.add_argument("--seed", type=int_range(0), default=0, help="which random nodes (default %(default)d)")
    tc.add_argument(
        "--reference-substeps",
        type=int_range(2),
        default=64,
        help="reference step = the table's timestep / this (default %(default)d)",
    )
    tc.add_argument("-o", "--output", help="also write the result as JSON here")
    tc.add_argument("--threads", type=int_range(0), default=0, help="simulation threads (0: all CPUs)")
    tc.set_defaults(func=cmd_table_check)

    s = sub.add_parser("sim", help="the push scene: export MJCF, simulate pushes")
    ssub = s.add_subparsers(dest="sim_command", required=True)
    ex = ssub.add_parser(
        "export-xml",
        help="write the scene's MJCF for one object",
        description="OBJECT settings are key=value: mass=KG friction=MU size=HX,HY,HZ (half-extents, m).",
    )
    ex.add_argument("object", nargs="*", metavar="OBJECT", help="key=value settings of the box")
    _add_scene_options(ex)
    ex.add_argument("-o", "--output", required=True)
    ex.set_defaults(func=cmd_export_xml)

    pu = ssub.add_parser(
        "pushes",
        help="simulate pushes and write a push log",
        description=(
            "Reads PUSHES (object_id,speed and optional mass,friction,size_x,size_y,size_z) and writes a push "
            "log object_id,speed,displacement,stop_time plus the physics used. With --model, the pushes run "
            "on that MJCF (it must name body/geom 'box' with a free joint, slide joint 'push', velocity "
            "actuator 'servo', and <custom><numeric name='stroke'>)."
        ),
    )
    pu.add_argument("pushes", help="CSV of pushes to simulate")
    pu.add_argument("--model", help="user MJCF file (default: the built-in scene)")
    _add_scene_options(pu)
    pu.add_argument("-o", "--output", required=True)
    pu.add_argument("--threads", type=int_range(0), default=0)
    pu.set_defaults(func=cmd_pushes)


def _add_scene_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", help="config.yaml to take the 'scene' section from")
    p.add_argument("--scene-json", type=json_arg, help="scene settings as JSON (overrides --config)")


def _config_section(path: str, key: str) -> Any:
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


def scene_from_args(args: argparse.Namespace, compile_model: bool = False) -> SceneConfig:
    """The scene of --scene-json (or --config's ``scene``), checked; bad settings are a UserError."""
    from imply.config_check import ConfigError, check_scene

    cfg, where = None, "--scene-json"
    if getattr(args, "config", None):
        cfg, where = _config_section(args.config, "scene"), f"--config {args.config}: scene"
    if getattr(args, "scene_json", None) is not None:
        cfg, where = args.scene_json, "--scene-json"
    try:
        return check_scene(cfg, compile_model=compile_model, where=where)
    except ConfigError as exc:
        raise UserError(str(exc)) from exc


# -- imply score ----------------------------------------------------------------


@dataclass(frozen=True)
class RolloutRows:
    """A checked rollouts file as arrays, one entry per row (see :func:`read_rollouts`)."""

    objects: list[str]  # object ids in order of first appearance
    codes: np.ndarray  # (n,) each row's index into objects
    is_rollout: np.ndarray  # (n,) bool: rollout, else calibration
    speed: np.ndarray
    displacement: np.ndarray


def read_rollouts(path: str | Path, table: PushTable) -> RolloutRows:
    """Read and check a rollouts CSV (or parquet) file for scoring (see ``imply score``).

    Refused, with the row and column named: unknown roles, negative displacements,
    speeds outside the table, empty object ids, objects with fewer than 2 rollouts, and
    two rows of one object with the same role and speed (a rollout set holds one
    prediction per speed). A plainly valid CSV file is read and checked without pandas
    (:func:`imply.tabular.read_plain_csv`); any problem sends it through
    :func:`imply.tabular.read_table`, whose messages give the line in the file.
    """
    from imply.tabular import InputError, read_plain_csv

    plain = read_plain_csv(path, ["object_id", "role"], ["speed", "displacement"])
    if plain is not None:
        roles, ids = plain["role"], plain["object_id"]
        role_ok = np.array([r in ROLES for r in roles.values], dtype=bool)
        is_rollout = np.array([r == "rollout" for r in roles.values], dtype=bool)[roles.codes]
        rows = RolloutRows(ids.values, ids.codes, is_rollout, plain["speed"], plain["displacement"])
        try:
            if role_ok.all() and "" not in ids.values:
                _check_rollouts(path, rows, table, None)
                return rows
        except InputError:
            pass  # read again below, for a message that names the line
    return _read_rollouts_carefully(path, table)


def _read_rollouts_carefully(path: str | Path, table: PushTable) -> RolloutRows:
    import pandas as pd

    from imply.tabular import read_table_lines, row_error

    frame, lines = read_table_lines(path, ["object_id", "role", "speed", "displacement"], ["speed", "displacement"])
    roles = frame["role"].to_numpy()
    bad_role = ~np.isin(roles, ROLES)
    if bad_role.any():
        i = int(np.flatnonzero(bad_role)[0])
        raise row_error(path, i, "role", f"{roles[i]!r} is not 'calibration' or 'rollout'", lines)
    ids = frame["object_id"].to_numpy()
    if (ids == "").any():
        raise row_error(path, int(np.flatnonzero(ids == "")[0]), "object_id", "is empty", lines)
    codes, objects = pd.factorize(frame["object_id"], sort=False)
    rows = RolloutRows([str(o) for o in objects], codes.astype(np.int64), roles == "rollout",
                       frame["speed"].to_numpy(float), frame["displacement"].to_numpy(float))  # fmt: skip
    _check_rollouts(path, rows, table, lines)
    return rows


def _check_rollouts(path: str | Path, rows: RolloutRows, table: PushTable, lines: np.ndarray | None) -> None:
    """The checks on values, vectorised: 200,000 rows take a few milliseconds."""
    from imply.tabular import InputError, row_error, row_label

    d, v, codes = rows.displacement, rows.speed, rows.codes
    if (d < 0).any():
        i = int(np.flatnonzero(d < 0)[0])
        raise row_error(path, i, "displacement", f"{d[i]:g} is negative", lines)
    lo, hi = table.speed_range
    out = (v < lo * (1 - 1e-9)) | (v > hi * (1 + 1e-9))
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise row_error(path, i, "speed", f"{v[i]:g} is outside the table's speed range [{lo:g}, {hi:g}]", lines)
    n_rollouts = np.bincount(codes[rows.is_rollout], minlength=len(rows.objects))
    if (n_rollouts < 2).any():
        # codes number objects in order of first appearance: the smallest is the first in the file
        obj = int(np.flatnonzero(n_rollouts < 2)[0])
        raise row_error(path, int(np.flatnonzero(codes == obj)[0]), "object_id",
                        f"object {rows.objects[obj]!r} has {n_rollouts[obj]} rollout(s); at least 2 are needed",
                        lines)  # fmt: skip
    order = np.lexsort((v, rows.is_rollout, codes))
    same = (np.diff(codes[order]) == 0) & (np.diff(rows.is_rollout[order]) == 0) & (np.diff(v[order]) == 0)
    if same.any():
        # of all repeated pairs, the one whose second row comes first in the file
        pairs = np.flatnonzero(same)
        j = pairs[np.argmin(order[pairs + 1])]
        first, second = sorted((int(order[j]), int(order[j + 1])))
        role = "rollout" if rows.is_rollout[first] else "calibration"
        raise InputError(
            f"{path}: {row_label(path, first, lines)} and {row_label(path, second, lines)}: object "
            f"{rows.objects[codes[first]]!r} has two {role} rows at speed {v[first]:g}; a rollout set holds "
            "one prediction per speed, so remove one of them"
        )


def pad_sets(codes: np.ndarray, speeds: np.ndarray, displacements: np.ndarray, n_sets: int):
    """Rows grouped into NaN-padded (n_sets, K) speeds and displacements, in file order within a set.

    A stable sort by set puts each set's rows together; a row's column is its rank in
    its set. K is the largest set; absent terms have NaN displacements (and speeds,
    which the caller replaces).
    """
    counts = np.bincount(codes, minlength=n_sets)
    width = max(int(counts.max(initial=0)), 1)
    order = np.argsort(codes, kind="stable")
    sorted_codes = codes[order]
    starts = np.cumsum(counts) - counts
    column = np.arange(order.size) - starts[sorted_codes]
    v = np.full((n_sets, width), np.nan)
    d = np.full((n_sets, width), np.nan)
    v[sorted_codes, column] = speeds[order]
    d[sorted_codes, column] = displacements[order]
    return v, d


def score_rows(rows: RolloutRows, scorer: Scorer) -> dict[str, Any]:
    """Scores of every object, in order of first appearance, as the columns of SCORE_COLUMNS."""
    n = len(rows.objects)
    v, d, roll = rows.speed, rows.displacement, rows.is_rollout
    rv, rd = pad_sets(rows.codes[roll], v[roll], d[roll], n)
    # absent terms need a valid speed for the range check; their displacement stays NaN
    rv[np.isnan(rv)] = v[0]
    has_cal = not roll.all()
    cv = cd = None
    if has_cal:
        cv, cd = pad_sets(rows.codes[~roll], v[~roll], d[~roll], n)
        cv[np.isnan(cv)] = v[0]
    scores = scorer.score(rv, rd, cv, cd)
    out: dict[str, Any] = {"object_id": rows.objects, **{c: getattr(scores, c) for c in SCORE_COLUMNS[1:]}}
    if has_cal:
        # objects without calibration rows get no anchored score
        no_cal = ~np.isfinite(cd).any(axis=1)
        for c in ("anchored_disagreement", "anchored_mass_hat", "anchored_friction_hat"):
            out[c] = np.where(no_cal, np.nan, out[c])
    return out


def cmd_score(args: argparse.Namespace) -> int:
    from imply.io import write_columns
    from imply.score import Scorer
    from imply.table import OutOfRangeError
    from imply.tabular import InputError

    output = output_file(args.output, [args.rollouts, args.table])
    table = load_push_table(args.table)
    try:
        rows = read_rollouts(args.rollouts, table)
        threads = args.threads or os.cpu_count() or 1
        out = score_rows(rows, Scorer(table, grid=args.grid, floor=args.floor, threads=threads))
    except (InputError, OutOfRangeError) as exc:
        raise UserError(str(exc)) from exc
    write_columns(output, out)
    log.info("scored %d objects -> %s", len(rows.objects), output)
    return 0


# -- imply table build, imply sim --------------------------------------------------


def cmd_table_build(args: argparse.Namespace) -> int:
    from imply.config_check import ConfigError, table_grid
    from imply.table import CheckSettings, TableGrid, build_table, check_table, with_numerical_error

    output = output_file(args.output, [getattr(args, "config", None)])
    scene = scene_from_args(args, compile_model=True)
    grid_cfg, where = args.grid_json, "--grid-json"
    if grid_cfg is None and args.config:
        grid_cfg, where = _config_section(args.config, "table"), f"--config {args.config}: table"
    try:
        grid = table_grid(grid_cfg, where) if grid_cfg is not None else TableGrid()
    except ConfigError as exc:
        raise UserError(str(exc)) from exc
    try:
        check = CheckSettings.from_dict(args.check_json)
    except (TypeError, ValueError) as exc:
        raise UserError(f"--check-json: {exc}") from exc
    try:
        table = build_table(scene, grid, nthread=args.threads, progress=True)
    except (ValueError, RuntimeError) as exc:
        # the simulator refuses settings it cannot finish a push with; a failed cell names itself
        raise UserError(f"cannot build the table: {exc}") from exc
    if check.cells:
        log.info("measuring the table's numerical error on %d cells", check.cells)
        table = with_numerical_error(table, check_table(table, check, nthread=args.threads, progress=True))
        log.info("numerical error: %s", _error_line(table.meta["numerical_error"]))
    table.save(output)
    log.info("wrote %s", output)
    return 0


def _error_line(error: dict) -> str:
    worst = error["worst_cell"]
    return (
        f"max |delta log d| {error['max_abs_log_d']:.4f}, RMS {error['rms_log_d']:.4f} over {error['cells']} cells "
        f"(worst at v={worst['speed']:g}, m={worst['mass']:.3g}, mu={worst['friction']:.3g}); reference at "
        f"{error['reference_step_s'] * 1e6:.4g} us, its own error max {error['reference_error_max']:.4f}, "
        f"RMS {error['reference_error_rms']:.4f}"
    )


def cmd_table_check(args: argparse.Namespace) -> int:
    from imply.io import write_json
    from imply.table import CheckSettings, check_table

    output = output_file(args.output, [args.table]) if args.output else None
    table = load_push_table(args.table, option="TABLE")
    settings = CheckSettings(cells=args.cells, seed=args.seed, reference_substeps=args.reference_substeps)
    try:
        error = check_table(table, settings, nthread=args.threads, progress=True)
    except ValueError as exc:
        raise UserError(f"cannot check {args.table}: {exc}") from exc
    recorded = table.meta.get("numerical_error")
    print(_error_line(error))
    if recorded:
        print(f"recorded in the table when built: {_error_line(recorded)}")
    if output is not None:
        write_json(output, error)
    return 0


def parse_object_settings(items: list[str]) -> dict:
    settings: dict = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep:
            raise UserError(f"OBJECT setting {item!r} is not key=value")
        try:
            if key == "size":
                parts = [float(x) for x in value.split(",")]
                if len(parts) != 3 or not all(0 < x < float("inf") for x in parts):
                    raise ValueError
                settings["half_extents"] = tuple(parts)
            elif key in ("mass", "friction"):
                settings[key] = float(value)
                if not 0 < settings[key] < float("inf"):
                    raise ValueError
            else:
                raise UserError(f"unknown OBJECT setting {key!r} (use mass, friction, size)")
        except ValueError:
            raise UserError(f"OBJECT setting {item!r}: bad value") from None
    return settings


def cmd_export_xml(args: argparse.Namespace) -> int:
    import mujoco

    from imply.io import write_text
    from imply.sim import build_xml

    output = output_file(args.output, [getattr(args, "config", None)])
    scene = scene_from_args(args)
    xml = build_xml(scene, **parse_object_settings(args.object))
    try:
        mujoco.MjModel.from_xml_string(xml)  # fail here, not in the user's hands
    except ValueError as exc:
        raise UserError(f"the scene does not compile: {exc}") from exc
    write_text(output, xml)
    log.info("wrote %s", output)
    return 0


def cmd_pushes(args: argparse.Namespace) -> int:
    import mujoco

    from imply.io import write_csv
    from imply.sim import simulate_pushes
    from imply.tabular import row_error

    output = output_file(args.output, [args.pushes, args.model, getattr(args, "config", None)])
    size_cols = ["size_x", "size_y", "size_z"]
    frame, lines = _read_or_fail(args.pushes, ["object_id", "speed"], ["speed"], ["mass", "friction", *size_cols])
    for col in ["speed", "mass", "friction", *size_cols]:
        if col in frame and (frame[col] <= 0).any():
            i = int(np.flatnonzero(frame[col].to_numpy() <= 0)[0])
            raise UserError(str(row_error(args.pushes, i, col, "must be positive", lines)))
    model = None
    if args.model:
        if not Path(args.model).is_file():
            raise UserError(f"--model {args.model}: no such file")
        try:
            model = mujoco.MjModel.from_xml_path(args.model)
        except Exception as exc:
            raise UserError(f"--model {args.model}: {exc}") from exc
        if not model.opt.timestep > 0:
            raise UserError(f"--model {args.model}: timestep {model.opt.timestep:g} must be positive")
    has_size = all(c in frame for c in size_cols)
    if model is not None and has_size:
        raise UserError("size_x/size_y/size_z columns cannot vary the box of a user --model; edit the MJCF instead")
    scene = scene_from_args(args) if model is None else None
    try:
        result = simulate_pushes(
            frame["speed"].to_numpy(),
            frame["mass"].to_numpy() if "mass" in frame else None,
            frame["friction"].to_numpy() if "friction" in frame else None,
            frame[size_cols].to_numpy() if has_size else None,
            scene=scene, model=model, nthread=args.threads, progress=True,
        )  # fmt: skip
    except (KeyError, ValueError) as exc:
        raise UserError(f"cannot simulate on this model: {exc}") from exc
    out = frame.copy()
    out["displacement"] = result.displacement
    out["stop_time"] = result.stop_time
    out["ok"] = result.ok
    write_csv(output, out)
    log.info("simulated %d pushes (%d failed checks) -> %s", len(out), int((~result.ok).sum()), output)
    return 0


def _read_or_fail(path, required, numeric, optional_numeric=()):
    from imply.tabular import InputError, read_table_lines

    try:
        return read_table_lines(path, required, numeric, optional_numeric)
    except InputError as exc:
        raise UserError(str(exc)) from exc
