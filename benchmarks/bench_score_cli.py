"""Benchmark of `imply score` for users with many objects: a naive per-object path against the project's.

Run: python benchmarks/bench_score_cli.py [--table T.npz] [--objects 28572] [--repeats 3] [--git-rev REV]

Writes a rollouts CSV of N objects, each with 5 rollouts at the query speeds and 2
calibration pushes (7 rows per object: 28,572 objects are 200,004 rows), displacements
from the table with log-normal noise. Then, in this process:

- naive path: reading, checking, grouping and padding with pandas, one groupby and a
  Python loop per object (as `imply score` once did), around the project's
  :class:`imply.score.Scorer` on one thread;
- project path: :func:`imply.score_file.read_rollouts`, :func:`score_rows` and
  :class:`imply.score.Scorer` on every CPU, as the command runs them.

Both include reading the CSV and writing the scores; it prints seconds, rows per second,
the ratio, and how far the two outputs differ. It also times the command's start (the
imports before any work, the old set against the new one) and the whole command as a
user runs it (a fresh `python -m imply.cli score`). The scorer as it was before the
vectorised path is measured only by running that revision's own code: with --git-rev,
the command of that revision (e.g. 5d3bc0e) is run the same way, for an end to end
before/after. Benchmarks measure; they assert nothing.
"""

from __future__ import annotations

import argparse
import io
import os
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from imply.input_files import read_table, row_error
from imply.io import write_columns, write_csv
from imply.score import Scorer
from imply.score_file import SCORE_COLUMNS, read_rollouts, score_rows
from imply.table import PushTable

QUERY = [0.25, 0.4, 0.55, 0.7, 0.85]
CALIB = [0.3, 0.8]
TINY_GRID = (
    '{"speeds": {"min": 0.15, "max": 1.05, "n": 7}, "masses": {"min": 0.2, "max": 2.0, "n": 6}, '
    '"frictions": {"min": 0.1, "max": 0.6, "n": 6}}'
)


# -- the naive path: per-object pandas around the project's scorer ----------------------


def naive_read_rollouts(path, table: PushTable) -> pd.DataFrame:
    """Read and check a rollouts file with pandas, one groupby and a Python loop over objects."""
    frame = read_table(path, ["object_id", "role", "speed", "displacement"], ["speed", "displacement"])
    roles = frame["role"].str.strip()
    bad_role = ~roles.isin(["calibration", "rollout"])
    if bad_role.any():
        i = int(np.flatnonzero(bad_role)[0])
        raise row_error(path, i, "role", f"{frame['role'].iloc[i]!r} is not 'calibration' or 'rollout'")
    frame["role"] = roles
    lo, hi = table.speed_range
    speeds = frame["speed"].to_numpy()
    out = (speeds < lo * (1 - 1e-9)) | (speeds > hi * (1 + 1e-9))
    if out.any():
        i = int(np.flatnonzero(out)[0])
        raise row_error(path, i, "speed", f"{speeds[i]:g} is outside the table's speed range [{lo:g}, {hi:g}]")
    counts = frame[frame["role"] == "rollout"].groupby("object_id", sort=False).size()
    for obj in frame["object_id"].unique():
        n = int(counts.get(obj, 0))
        if n < 2:
            i = int(np.flatnonzero(frame["object_id"].to_numpy() == obj)[0])
            raise row_error(path, i, "object_id", f"object {obj!r} has {n} rollout(s); at least 2 are needed")
    return frame


def naive_pad_sets(frame: pd.DataFrame, role: str, order: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """One role's pushes as (objects, pushes) arrays, padded with NaN, filled object by object."""
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
    v[np.isnan(v)] = frame["speed"].iloc[0]
    return v, d


def naive_score(path, table: PushTable, out_path) -> None:
    """The naive path: pandas frame, a loop per object, the project's :class:`Scorer` on one thread,
    pandas writer."""
    frame = naive_read_rollouts(path, table)
    order = list(frame["object_id"].unique())
    rv, rd = naive_pad_sets(frame, "rollout", order)
    has_cal = (frame["role"] == "calibration").any()
    cv, cd = naive_pad_sets(frame, "calibration", order) if has_cal else (None, None)
    scores = Scorer(table, threads=1).score(rv, rd, cv, cd)
    out = pd.DataFrame({"object_id": order, **{c: getattr(scores, c) for c in SCORE_COLUMNS[1:]}})
    if has_cal:
        no_cal = ~np.isfinite(cd).any(axis=1)
        for c in ("anchored_disagreement", "anchored_mass_hat", "anchored_friction_hat"):
            out.loc[no_cal, c] = np.nan
    write_csv(out_path, out)


def project_score(path, table: PushTable, out_path) -> None:
    """`imply score` as it runs now."""
    rows = read_rollouts(path, table)
    write_columns(out_path, score_rows(rows, Scorer(table, threads=os.cpu_count() or 1)))


# -- inputs and timing -------------------------------------------------------------------


def make_rollouts(table: PushTable, n_objects: int, path: Path, seed: int = 0) -> int:
    rng = np.random.default_rng(seed)
    lo_m, hi_m = table.mass_range
    lo_f, hi_f = table.friction_range
    m = np.exp(rng.uniform(np.log(lo_m), np.log(hi_m), n_objects))
    mu = np.exp(rng.uniform(np.log(lo_f), np.log(hi_f), n_objects))
    per = len(CALIB) + len(QUERY)
    speeds = np.tile(CALIB + QUERY, n_objects)
    log_d = table.log_displacement(speeds, np.repeat(m, per), np.repeat(mu, per))
    log_d += rng.normal(0.0, 0.05, log_d.size)
    frame = pd.DataFrame(
        {
            "object_id": np.repeat([f"obj{i:06d}" for i in range(n_objects)], per),
            "role": np.tile(["calibration"] * len(CALIB) + ["rollout"] * len(QUERY), n_objects),
            "speed": speeds,
            "displacement": np.exp(log_d),
        }
    )
    frame.to_csv(path, index=False, float_format="%.6g")
    return len(frame)


def best_of(repeats: int, func) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        func()
        times.append(time.perf_counter() - t0)
    return min(times)


# what the old command imported before any work (every command group eagerly), in today's module names
STARTUP_OLD = "import imply.cli, pandas, mujoco, yaml, imply.score, imply.table, imply.sim, imply.cli.gap"
STARTUP_NEW = (
    "from imply.cli import build_parser; build_parser(); "
    "import imply.score_file, imply.score, imply.table, imply.input_files, imply.io, pyarrow.csv, pyarrow.compute"
)


def startup(code: str, repeats: int, env: dict | None = None) -> float:
    """Seconds to import what a command imports before its work, in a fresh interpreter."""
    probe = f"import time; t0 = time.perf_counter(); {code}; print(time.perf_counter() - t0)"
    return min(
        float(subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, check=True, env=env).stdout)
        for _ in range(repeats)
    )


def cli_seconds(args: list[str], repeats: int, env: dict | None = None) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        subprocess.run([sys.executable, "-m", "imply.cli", *args], check=True, capture_output=True, env=env)
        times.append(time.perf_counter() - t0)
    return min(times)


def checkout(rev: str, dest: Path) -> Path:
    """The package source of a git revision, unpacked (the work tree is not touched)."""
    root = Path(__file__).resolve().parents[1]
    blob = subprocess.run(["git", "-C", str(root), "archive", rev, "src"], check=True, capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(blob)) as tar:
        tar.extractall(dest, filter="data")
    return dest / "src"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--table", help="push table (.npz); default: build a 7 x 6 x 6 one (a few seconds)")
    ap.add_argument("--objects", type=int, default=28572, help="objects (7 rows each; default %(default)d)")
    ap.add_argument("--repeats", type=int, default=3, help="timings per measurement; the best is kept")
    ap.add_argument("--git-rev", help="also run `imply score` of this git revision end to end (e.g. 5d3bc0e)")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        table_path = Path(args.table) if args.table else tmp / "table.npz"
        if not args.table:
            subprocess.run(
                [sys.executable, "-m", "imply.cli", "table", "build", "--grid-json", TINY_GRID, "-o", str(table_path)],
                check=True,
                capture_output=True,
            )
        table = PushTable.load(table_path)
        src = tmp / "rollouts.csv"
        n_rows = make_rollouts(table, args.objects, src)
        print(f"{args.objects} objects, {n_rows} rows; table {table.log_d.shape}; {os.cpu_count()} CPUs")

        naive_out, project_out = tmp / "naive.csv", tmp / "project.csv"
        t_new = best_of(args.repeats, lambda: project_score(src, table, project_out))
        t_old = best_of(max(1, args.repeats - 1), lambda: naive_score(src, table, naive_out))
        a, b = pd.read_csv(naive_out), pd.read_csv(project_out)
        diff = max(float(np.nanmax(np.abs(a[c].to_numpy(float) - b[c].to_numpy(float)))) for c in SCORE_COLUMNS[1:])
        print("in process (read, check, group, score, write):")
        print(f"  naive per-object     {t_old:7.2f} s  {n_rows / t_old:12,.0f} rows/s")
        print(f"  project's path       {t_new:7.2f} s  {n_rows / t_new:12,.0f} rows/s")
        print(f"  ratio                {t_old / t_new:7.1f}x   (largest difference in any score: {diff:.2g})")

        s_old, s_new = startup(STARTUP_OLD, args.repeats), startup(STARTUP_NEW, args.repeats)
        print("start (imports before any work, fresh interpreter):")
        print(f"  old set {s_old:.2f} s, new set {s_new:.2f} s")

        cli = ["score", str(src), "--table", str(table_path), "-o", str(tmp / "cli.csv")]
        t_cli = cli_seconds(cli, args.repeats)
        print("whole command (python -m imply.cli score ..., wall clock):")
        print(f"  now                  {t_cli:7.2f} s  {n_rows / t_cli:12,.0f} rows/s")
        if args.git_rev:
            env = {**os.environ, "PYTHONPATH": str(checkout(args.git_rev, tmp / "old"))}
            t_rev = cli_seconds(cli, max(1, args.repeats - 1), env=env)
            print(f"  at {args.git_rev:<17} {t_rev:7.2f} s  {n_rows / t_rev:12,.0f} rows/s")
            print(f"  ratio                {t_rev / t_cli:7.1f}x")


if __name__ == "__main__":
    main()
