"""Running the diagnostic on push-log files: one checked request, its shared setup, then each log's report.

A :class:`DiagnoseRequest` holds everything a run needs, checked once by whoever builds
it (the CLI: :func:`imply.cli.common.diagnose_request`): the baseline table, the
candidates, the settings, the effect-table cache, and every push log (read and checked
against the table) with the report folder it goes to (checked by
:func:`check_report_folder`). :func:`run` loads what every diagnosis shares (the effect
tables, :func:`prepare`), then diagnoses each log into its folder, written beside it and
moved in whole (:func:`imply.io.write_folder`), so a report is never half-written and
nothing in the folder that an earlier report did not write is touched.
"""

from __future__ import annotations

import logging
import os
from dataclasses import dataclass, replace
from pathlib import Path

from tqdm.auto import tqdm

from imply.diagnose.analysis import DiagnosisConfig, Summary, check_in_simulator, diagnose
from imply.diagnose.conclusion.render import reference_text, verdict_text
from imply.diagnose.conclusion.simulator_check import Scene
from imply.diagnose.inference.fit import Problem
from imply.diagnose.inputs.probes import probes_beside, read_probes
from imply.diagnose.inputs.pushlog import PushLog, read_pushlog
from imply.diagnose.inputs.track_file import read_track, track_beside
from imply.diagnose.physics.candidates import Candidate, library_effects, needs_across
from imply.diagnose.physics.effect_tables import CoarseGrid, EffectTables, load_or_build
from imply.diagnose.reference import diagnose_against
from imply.diagnose.report import REPORT_FILES, write_report
from imply.io import check_folder, write_folder
from imply.table import PushTable

log = logging.getLogger("imply.diagnose")


@dataclass(frozen=True)
class Report:
    """One push log (read and checked against the table) and the report folder it goes to (checked); with a
    reference session of the same robot and boxes, recorded before the change (:mod:`imply.diagnose.reference`)."""

    pushlog: PushLog
    folder: Path
    reference: PushLog | None = None


@dataclass(frozen=True, kw_only=True)
class DiagnoseRequest:
    """A run of diagnoses, checked: the table, candidates, settings, effect-table cache and the reports to write."""

    table: PushTable
    candidates: tuple[Candidate, ...]
    options: DiagnosisConfig
    grid: CoarseGrid
    cache_dir: Path | None
    threads: int = 0
    # the scene the stated causes are written into and re-simulated in (None: the table's built-in scene)
    scene: Scene | None = None
    force: bool = False  # replace the files an earlier report wrote in a report folder
    plots: bool = True  # the reports' figures (a benchmark's reports are read as data)
    reports: tuple[Report, ...] = ()


@dataclass(frozen=True)
class Session:
    """What the diagnoses of one run share: the settings with the tables' model floors, and the tables."""

    table: PushTable
    candidates: tuple[Candidate, ...]
    options: DiagnosisConfig
    effect_tables: EffectTables
    plots: bool = True
    scene: Scene | None = None  # the scene the stated causes are put into (table_scene(table) where not given)
    threads: int = 0


def table_scene(table: PushTable) -> Scene:
    """The table's own push scene (its built-in MJCF at the scene settings it was built with)."""
    from imply.sim.scene import SceneConfig, build_xml

    return Scene(xml=build_xml(SceneConfig.from_dict(table.meta.get("scene"), "the table's scene")), name="built-in")


def user_scene(path: str | os.PathLike) -> Scene:
    """A user's push scene (MJCF file), checked as ``imply sim pushes --model`` checks it (ValueError naming it)."""
    from imply.sim.push_file import load_push_model
    from imply.sim.pushes import PushJoints, PushStepping

    model = load_push_model(path)
    try:
        PushJoints.of(model)
        PushStepping.of(model)
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    path = Path(path)
    return Scene(xml=path.read_text(), name=str(path), model_dir=str(path.resolve().parent))


def effect_tables(
    table: PushTable,
    candidates: list[Candidate] | tuple[Candidate, ...],
    *,
    options: DiagnosisConfig,
    grid: CoarseGrid,
    cache_dir: str | os.PathLike | None,
    nthread: int = 0,
    progress: bool = True,
) -> EffectTables:
    """The effect tables the candidates need (from the cache, or simulated into it)."""
    return load_or_build(
        table,
        library_effects(list(candidates)),
        grid,
        cache_dir,
        nthread=nthread,
        progress=progress,
        across=needs_across(list(candidates)),
        aux=options.observables().any_aux,
    )


def prepare(request: DiagnoseRequest, *, progress: bool = True) -> Session:
    """Load (or simulate and cache) the effect tables; the floors default to the tables' measured ones."""
    options = request.options
    etables = effect_tables(
        request.table,
        request.candidates,
        options=options,
        grid=request.grid,
        cache_dir=request.cache_dir,
        nthread=request.threads,
        progress=progress,
    )
    floor = etables.meta.get("model_floor") or {}
    if options.model_floor is None:
        options = options.replace(model_floor=floor.get("rms"))
    if options.stop_time_floor is None and floor.get("stop_time"):
        options = options.replace(stop_time_floor=floor["stop_time"]["rms"])
    return Session(
        request.table,
        request.candidates,
        options,
        etables,
        plots=request.plots,
        scene=request.scene or table_scene(request.table),
        threads=request.threads,
    )


def read_checked_pushlog(path: str | os.PathLike, table: PushTable, track: str | os.PathLike | None = None) -> PushLog:
    """A push log checked against the table's ranges (InputError naming the row and column), with the box's
    track from ``track``, or else from the file beside the log named ``<stem>.track.csv`` (or ``.parquet``)
    where there is one (:mod:`imply.diagnose.inputs.track_file`), and its calibration probes from the file beside it
    named ``<stem>.probes.csv`` (or ``.parquet``) where there is one (:mod:`imply.diagnose.inputs.probes`)."""
    pushlog = read_pushlog(path, table.speed_range, mass_range=table.mass_range, friction_range=table.friction_range)
    track = track or track_beside(path)
    pushlog = read_track(track, pushlog) if track else pushlog
    probes = probes_beside(path)
    if probes:
        checked = read_probes(
            probes,
            objects=pushlog.objects,
            log_path=pushlog.path,
            mass=pushlog.mass,
            speed_range=table.speed_range,
            mass_range=table.mass_range,
        )
        pushlog = replace(pushlog, probes=checked)
    return pushlog


def check_report_folder(folder: str | os.PathLike, force: bool, inputs) -> None:
    """Refuse, before any work, a report folder whose writing would destroy files (OutputError)."""
    check_folder(folder, REPORT_FILES, force, inputs)


def diagnose_report(report: Report, session: Session, *, force: bool = False) -> Summary:
    """Diagnose one push log into its report folder; returns the summary."""
    opts = session.options
    if report.reference is not None:
        diag = diagnose_against(
            report.pushlog,
            report.reference,
            table=session.table,
            etables=session.effect_tables,
            candidates=list(session.candidates),
            opts=opts,
        )
    else:
        problem = Problem.of(
            report.pushlog,
            session.table,
            session.effect_tables,
            grid=opts.grid,
            observables=opts.observables(),
        )
        diag = diagnose(problem, list(session.candidates), opts)
    scene = session.scene or table_scene(session.table)
    text = reference_text if report.reference is not None else verdict_text
    diag = check_in_simulator(diag, scene, nthread=session.threads, text=text)
    write_folder(report.folder, lambda tmp: write_report(diag, tmp, plots=session.plots), force=force)
    v = diag.summary.verdict
    log.info("%s: %s, %s -> %s", report.pushlog.path, v.adequacy, v.identification, report.folder)
    return diag.summary


def run(request: DiagnoseRequest, *, progress: bool = True) -> list[Summary]:
    """Every report of a checked request: the shared setup once, then each push log's diagnosis."""
    session = prepare(request, progress=progress)
    reports = tqdm(request.reports, desc="diagnoses", unit="log", disable=not progress or len(request.reports) < 2)
    return [diagnose_report(r, session, force=request.force) for r in reports]
