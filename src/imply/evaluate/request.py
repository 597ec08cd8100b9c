"""One ``imply evaluate`` request, end to end: what the command asks, checked, run and written.

:func:`run_request` checks the report folder before any work, loads the suite, runs a
``--command`` generator for the cases it still owes (exporting the suite beside the
report once), checks every folder of generated videos before any scoring, scores every
model and rollouts file, writes the report and removes the resume cache it made. The
command line (:mod:`imply.cli.evaluate`) only parses options into an
:class:`EvaluateRequest` and reports the outcome.
"""

from __future__ import annotations

import logging
import shutil
from dataclasses import dataclass, field
from pathlib import Path

from imply.evaluate.config import EvaluateConfig

log = logging.getLogger("imply")


@dataclass(frozen=True)
class EvaluateRequest:
    """What to score and where: models run in process (``MODULE:FACTORY``), rollouts files, folders of generated
    videos, and a generation ``command`` (its model named ``name``), on the suite folder ``suite``, into the report
    folder ``output`` (None only with ``check``: check the video folders and score nothing)."""

    suite: Path
    output: Path | None
    settings: EvaluateConfig
    models: tuple[str, ...] = ()
    rollouts: tuple[Path, ...] = ()
    videos: tuple[Path, ...] = ()
    command: str | None = None
    name: str = "command"
    check: bool = False
    force: bool = False
    cache: Path | None = None  # finished batches for a resumed run; None: beside the report, removed after it
    keep_cache: bool = True  # False: no batches on disk at all
    progress: bool = True
    inputs: tuple[Path, ...] = field(init=False)

    def __post_init__(self) -> None:
        if not (self.models or self.rollouts or self.videos or self.command):
            raise ValueError("give at least one --model MODULE:FACTORY, --rollouts FILE, --videos FOLDER or --command")
        if self.check and not self.videos:
            raise ValueError("--check checks --videos folders: give at least one")
        if self.output is None and (not self.check or self.command):
            raise ValueError("give the report folder: -o REPORT")
        object.__setattr__(self, "inputs", (*self.rollouts, *self.videos))


def generate_videos(command: str, *, suite, conditions: tuple[str, ...], out: Path, name: str) -> Path:
    """Export the suite beside the report ``out`` (once, or again if the suite or the conditions changed), run the
    user's generation ``command`` for the cases not generated yet, and return its videos folder (named ``name``).
    Raises :class:`imply.evaluate.video_package.CommandError` when the command fails."""
    from imply.evaluate.video_package import export_package, read_manifest, run_command

    package = out.with_name(out.name + ".package")
    videos = out.with_name(out.name + ".videos") / name
    made = read_manifest(package) if package.exists() else None
    if made is None or made["suite"] != suite.checksum or made["conditions"] != list(conditions):
        if package.exists():
            shutil.rmtree(package)
        export_package(suite, package, conditions=conditions)
    n = run_command(command, package=package, videos=videos, log_path=out.with_name(out.name + ".command.log"))
    log.info("--command generated %d case(s) -> %s", n, videos)
    return videos


def checked_videos(folders, suite, conditions: tuple[str, ...]) -> list:
    """Every folder of generated videos checked and read as rollouts; one
    :class:`imply.evaluate.video_package.VideoFolderError` holding every problem of every folder."""
    from imply.evaluate.video_package import VideoFolderError, read_videos

    out, problems = [], []
    for folder in folders:
        try:
            out.append(read_videos(folder, suite, conditions))
        except VideoFolderError as exc:
            problems += exc.problems
    if problems:
        raise VideoFolderError([*problems[:-1], problems[-1] + " (nothing scored)"])
    return out


def run_request(request: EvaluateRequest) -> list:
    """Score the request's models and write the report; returns the evaluations (none for a ``check``)."""
    from imply.evaluate.harness import evaluate
    from imply.evaluate.report import check_report_folder, write_report
    from imply.evaluate.suite import load_suite

    out, settings = request.output, request.settings
    if not request.check:
        check_report_folder(out, force=request.force, inputs=list(request.inputs))
    suite = load_suite(request.suite)
    videos = list(request.videos)
    if request.command:
        videos.append(
            generate_videos(request.command, suite=suite, conditions=settings.conditions, out=out, name=request.name)
        )
    read = checked_videos(videos, suite, settings.conditions)  # always before any scoring
    if request.check:
        log.info("%d folder(s) of videos checked: nothing wrong", len(read))
        return []
    cache = None if not request.keep_cache else request.cache or out.with_name(out.name + ".cache")
    evaluations = evaluate(
        list(request.models),
        suite=suite,
        rollouts=[*request.rollouts, *read],
        settings=settings,
        cache_dir=cache,
        progress=request.progress,
    )
    write_report(evaluations, out, force=request.force, inputs=list(request.inputs))
    if cache is not None and request.cache is None and cache.exists():
        shutil.rmtree(cache, ignore_errors=True)
    return evaluations
