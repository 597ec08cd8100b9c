"""Core subcommands: ``imply score``, ``imply table build``, ``imply sim export-xml|pushes``."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import mujoco
import numpy as np
import pandas as pd
import yaml

from imply.cli import UserError, json_arg
from imply.io import write_csv, write_text
from imply.score import DEFAULT_FLOOR, DEFAULT_GRID, Scorer
from imply.sim import SceneConfig, build_xml, simulate_pushes
from imply.table import OutOfRangeError, PushTable, TableError, TableGrid, build_table
from imply.tabular import InputError, read_table, row_error

log = logging.getLogger("imply")

SCORE_COLUMNS = [
    "object_id", "n_rollouts", "self_disagreement", "anchored_disagreement",
    "mass_hat", "friction_hat", "anchored_mass_hat", "anchored_friction_hat",
]  # fmt: skip


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("score", help="score rollout sets: self and anchored disagreement per object")
    p.add_argument("rollouts", help="CSV with object_id,role,speed,displacement (role: calibration|rollout; metres)")
    p.add_argument("--table", required=True, help="push table (.npz) from 'imply table build'")
    p.add_argument("-o", "--output", required=True, help="scores CSV to write")
    p.add_argument("--floor", type=float, default=DEFAULT_FLOOR, help="readout floor in metres (default %(default)g)")
    p.add_argument("--grid", type=int, default=DEFAULT_GRID, help="search grid points per axis (default %(default)d)")
    p.set_defaults(func=cmd_score)

    t = sub.add_parser("table", help="build the push table f(v, m, mu) -> log d")
    tsub = t.add_subparsers(dest="table_command", required=True)
    tb = tsub.add_parser("build", help="simulate every cell and write the table")
    _add_scene_options(tb)
    tb.add_argument("--grid-json", type=json_arg, help="table axes as JSON (config key 'table')")
    tb.add_argument("-o", "--output", required=True)
    tb.add_argument("--threads", type=int, default=0, help="simulation threads (0: all CPUs)")
    tb.set_defaults(func=cmd_table_build)

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
    pu.add_argument("--threads", type=int, default=0)
    pu.set_defaults(func=cmd_pushes)


def _add_scene_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--config", help="config.yaml to take the 'scene' section from")
    p.add_argument("--scene-json", type=json_arg, help="scene settings as JSON (overrides --config)")


def scene_from_args(args: argparse.Namespace) -> SceneConfig:
    cfg = None
    if getattr(args, "config", None):
        with open(args.config) as fh:
            cfg = (yaml.safe_load(fh) or {}).get("scene")
    if getattr(args, "scene_json", None) is not None:
        cfg = args.scene_json
    try:
        return SceneConfig.from_dict(cfg)
    except (TypeError, ValueError) as exc:
        raise UserError(f"scene settings: {exc}") from exc


def read_rollouts(path: str | Path, table: PushTable) -> pd.DataFrame:
    """Read and check a rollouts CSV for scoring (see ``imply score``)."""
    frame = read_table(path, ["object_id", "role", "speed", "displacement"], ["speed", "displacement"])
    roles = frame["role"].str.strip()
    bad_role = ~roles.isin(["calibration", "rollout"])
    if bad_role.any():
        i = int(np.flatnonzero(bad_role)[0])
        raise row_error(path, i, "role", f"{frame['role'].iloc[i]!r} is not 'calibration' or 'rollout'")
    frame["role"] = roles
    neg = frame["displacement"].to_numpy() < 0
    if neg.any():
        i = int(np.flatnonzero(neg)[0])
        raise row_error(path, i, "displacement", f"{frame['displacement'].iloc[i]:g} is negative")
    lo, hi = table.speed_range
    speeds = frame["speed"].to_numpy()
    out = (speeds < lo * (1 - 1e-9)) | (speeds > hi * (1 + 1e-9))
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise row_error(path, i, "speed", f"{speeds[i]:g} is outside the table's speed range [{lo:g}, {hi:g}]")
    empty_id = frame["object_id"].str.strip() == ""
    if empty_id.any():
        raise row_error(path, int(np.flatnonzero(empty_id)[0]), "object_id", "is empty")
    counts = frame[frame["role"] == "rollout"].groupby("object_id", sort=False).size()
    for obj in frame["object_id"].unique():
        n = int(counts.get(obj, 0))
        if n < 2:
            i = int(np.flatnonzero(frame["object_id"].to_numpy() == obj)[0])
            raise row_error(path, i, "object_id", f"object {obj!r} has {n} rollout(s); at least 2 are needed")
    return frame


def pad_sets(frame: pd.DataFrame, role: str, order: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """Per object (in ``order``), its ``role`` rows as NaN-padded (N, K) speeds and displacements."""
    part = frame[frame["role"] == role]
    groups = {k: g for k, g in part.groupby("object_id", sort=False)}
    width = max([len(g) for g in groups.values()] + [1])
    v = np.full((len(order), width), np.nan)
    d = np.full((len(order), width), np.nan)
    for i, obj in enumerate(order):
        g = groups.get(obj)
        if g is not None:
            v[i, : len(g)] = g["speed"].to_numpy()
            d[i, : len(g)] = g["displacement"].to_numpy()
    # absent terms need a valid speed for the range check; their displacement stays NaN
    v[np.isnan(v)] = frame["speed"].iloc[0]
    return v, d


def score_frame(frame: pd.DataFrame, scorer: Scorer) -> pd.DataFrame:
    """Scores of every object in a checked rollouts frame, in order of first appearance."""
    order = list(frame["object_id"].unique())
    rv, rd = pad_sets(frame, "rollout", order)
    has_cal = (frame["role"] == "calibration").any()
    cv, cd = pad_sets(frame, "calibration", order) if has_cal else (None, None)
    scores = scorer.score(rv, rd, cv, cd)
    out = pd.DataFrame({"object_id": order, **{c: getattr(scores, c) for c in SCORE_COLUMNS[1:]}})
    if has_cal:
        # objects without calibration rows get no anchored score
        no_cal = ~np.isfinite(cd).any(axis=1)
        for c in ("anchored_disagreement", "anchored_mass_hat", "anchored_friction_hat"):
            out.loc[no_cal, c] = np.nan
    return out


def cmd_score(args: argparse.Namespace) -> int:
    try:
        table = PushTable.load(args.table)
    except TableError as exc:
        raise UserError(f"--table: {exc}") from exc
    try:
        frame = read_rollouts(args.rollouts, table)
        scorer = Scorer(table, grid=args.grid, floor=args.floor)
        out = score_frame(frame, scorer)
    except (InputError, OutOfRangeError) as exc:
        raise UserError(str(exc)) from exc
    except ValueError as exc:
        raise UserError(str(exc)) from exc
    write_csv(args.output, out)
    log.info("scored %d objects -> %s", len(out), args.output)
    return 0


def cmd_table_build(args: argparse.Namespace) -> int:
    scene = scene_from_args(args)
    grid_cfg = args.grid_json
    if grid_cfg is None and args.config:
        with open(args.config) as fh:
            grid_cfg = (yaml.safe_load(fh) or {}).get("table")
    grid = TableGrid.from_dict(grid_cfg) if grid_cfg else TableGrid()
    table = build_table(scene, grid, nthread=args.threads, progress=True)
    table.save(args.output)
    log.info("wrote %s", args.output)
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
                if len(parts) != 3 or min(parts) <= 0:
                    raise ValueError
                settings["half_extents"] = tuple(parts)
            elif key in ("mass", "friction"):
                settings[key] = float(value)
                if not settings[key] > 0:
                    raise ValueError
            else:
                raise UserError(f"unknown OBJECT setting {key!r} (use mass, friction, size)")
        except ValueError:
            raise UserError(f"OBJECT setting {item!r}: bad value") from None
    return settings


def cmd_export_xml(args: argparse.Namespace) -> int:
    scene = scene_from_args(args)
    xml = build_xml(scene, **parse_object_settings(args.object))
    mujoco.MjModel.from_xml_string(xml)  # fail here, not in the user's hands
    write_text(args.output, xml)
    log.info("wrote %s", args.output)
    return 0


def cmd_pushes(args: argparse.Namespace) -> int:
    size_cols = ["size_x", "size_y", "size_z"]
    frame = _read_or_fail(args.pushes, ["object_id", "speed"], ["speed"], ["mass", "friction", *size_cols])
    for col in ["speed", "mass", "friction", *size_cols]:
        if col in frame and (frame[col] <= 0).any():
            i = int(np.flatnonzero(frame[col].to_numpy() <= 0)[0])
            raise UserError(str(row_error(args.pushes, i, col, "must be positive")))
    model = None
    if args.model:
        try:
            model = mujoco.MjModel.from_xml_path(args.model)
        except Exception as exc:
            raise UserError(f"--model {args.model}: {exc}") from exc
    has_size = all(c in frame for c in size_cols)
    if model is not None and has_size:
        raise UserError("size_x/size_y/size_z columns cannot vary the box of a user --model; edit the MJCF instead")
    try:
        result = simulate_pushes(
            frame["speed"].to_numpy(),
            frame["mass"].to_numpy() if "mass" in frame else None,
            frame["friction"].to_numpy() if "friction" in frame else None,
            frame[size_cols].to_numpy() if has_size else None,
            scene=scene_from_args(args), model=model, nthread=args.threads, progress=True,
        )  # fmt: skip
    except (KeyError, ValueError) as exc:
        raise UserError(f"cannot simulate on this model: {exc}") from exc
    out = frame.copy()
    out["displacement"] = result.displacement
    out["stop_time"] = result.stop_time
    out["ok"] = result.ok
    write_csv(args.output, out)
    log.info("simulated %d pushes (%d failed checks) -> %s", len(out), int((~result.ok).sum()), args.output)
    return 0


def _read_or_fail(path, required, numeric, optional_numeric=()):
    try:
        return read_table(path, required, numeric, optional_numeric)
    except InputError as exc:
        raise UserError(str(exc)) from exc
