"""Running the diagnostic on push-log files: set up once (table, candidates, effect tables), diagnose each log.

:func:`prepare` loads what every diagnosis of a session shares; :func:`diagnose_file`
diagnoses one push log into a report folder, written beside it and moved in whole
(:func:`imply.io.write_folder`), so a report is never half-written and nothing in the
folder that an earlier report did not write is touched.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass
from pathlib import Path

from imply.diagnose.analysis import DiagnosisConfig, diagnose
from imply.diagnose.candidates import Candidate, library_effects, needs_across
from imply.diagnose.effect_tables import CoarseGrid, EffectTables, load_or_build
from imply.diagnose.fit import Problem
from imply.diagnose.pushlog import PushLog, read_pushlog
from imply.diagnose.report import REPORT_FILES, write_report
from imply.io import check_folder, write_folder
from imply.table import PushTable

log = logging.getLogger("imply.diagnose")


@dataclass(frozen=True)
class Session:
    """What the diagnoses of one run share."""

    table: PushTable
    candidates: list[Candidate]
    options: DiagnosisConfig
    effect_tables: EffectTables


def effect_tables(
    table: PushTable,
    candidates: list[Candidate],
    options: DiagnosisConfig,
    grid: CoarseGrid,
    cache_dir: str | os.PathLike | None,
    *,
    nthread: int = 0,
    progress: bool = True,
) -> EffectTables:
    """The effect tables the candidates need (from the cache, or simulated into it)."""
    return load_or_build(
        table, library_effects(candidates), grid, cache_dir, nthread=nthread, progress=progress,
        across=needs_across(candidates), stop_time=options.use_stop_time,
    )  # fmt: skip


def prepare(
    table: PushTable,
    candidates: list[Candidate],
    options: DiagnosisConfig,
    grid: CoarseGrid,
    cache_dir: str | os.PathLike | None,
    *,
    nthread: int = 0,
    progress: bool = True,
) -> Session:
    """Load (or simulate and cache) the effect tables; the floors default to the tables' measured ones."""
    etables = effect_tables(table, candidates, options, grid, cache_dir, nthread=nthread, progress=progress)
    floor = etables.meta.get("model_floor") or {}
    if options.model_floor is None:
        options = options.replace(model_floor=floor.get("rms"))
    if options.stop_time_floor is None and floor.get("stop_time"):
        options = options.replace(stop_time_floor=floor["stop_time"]["rms"])
    return Session(table, candidates, options, etables)


def read_checked_pushlog(path: str | os.PathLike, table: PushTable) -> PushLog:
    """A push log checked against the table's ranges (InputError naming the row and column)."""
    return read_pushlog(path, table.speed_range, mass_range=table.mass_range, friction_range=table.friction_range)


def check_report_folder(folder: str | os.PathLike, force: bool, inputs) -> None:
    """Refuse, before any work, a report folder whose writing would destroy files (OutputError)."""
    check_folder(folder, REPORT_FILES, force, inputs)


def diagnose_file(
    pushlog_path: str | os.PathLike, output: str | os.PathLike, session: Session, *, force: bool = False
) -> dict:
    """Diagnose one push log into the report folder ``output``; returns the summary."""
    check_report_folder(output, force, [pushlog_path])
    pushlog = read_checked_pushlog(pushlog_path, session.table)
    opts = session.options
    problem = Problem.of(
        pushlog, session.table, session.effect_tables, grid=opts.grid, use_measured=opts.use_measured,
        use_stop_time=opts.use_stop_time,
    )  # fmt: skip
    diag = diagnose(problem, session.candidates, opts)
    write_folder(Path(output), lambda tmp: write_report(diag, tmp), force=force)
    v = diag.summary.verdict
    log.info("%s: verdict %s (%s) -> %s", pushlog_path, v.verdict, v.reason, output)
    return diag.summary
