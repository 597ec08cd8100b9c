"""The last run's time, rule by rule: Snakemake's per-rule benchmarks read into the reproduction report.

Every rule of the workflow writes ``results/benchmarks/<rule>/<wildcards>.tsv`` (Snakemake's
``benchmark:`` directive: wall seconds ``s``, ``cpu_time``, ``max_rss`` in MB, ...). A
job's end is its file's modification time, its start that less its wall time.
:func:`read_benchmarks` reads them; :func:`by_rule` sums them per rule; :func:`alone` reads
the timeline for the time a core stood idle and the jobs that ran alone meanwhile: the
jobs the run waited on (what a critical path names, read off the timeline, with no copy
of the DAG).
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass
from pathlib import Path


@dataclass(frozen=True)
class Job:
    """One job of the last run: its rule and wildcards, wall and CPU seconds, peak memory, and when it ended."""

    rule: str
    wildcards: str  # "all" for a rule without wildcards
    seconds: float
    cpu_seconds: float
    max_rss_mb: float
    end: float  # seconds since the epoch

    @property
    def start(self) -> float:
        return self.end - self.seconds

    @property
    def name(self) -> str:
        return self.rule if self.wildcards == "all" else f"{self.rule} ({self.wildcards})"


def _number(row: dict, key: str) -> float:
    try:
        return float(row.get(key, "nan"))
    except ValueError:
        return float("nan")


def read_benchmarks(folder: str | Path) -> list[Job]:
    """Every benchmark file under ``folder`` (``<rule>/<wildcards>.tsv``), oldest end first (none: an empty list)."""
    folder = Path(folder)
    jobs = []
    for path in sorted(folder.glob("*/*.tsv")) if folder.is_dir() else []:
        with open(path, newline="") as fh:
            rows = list(csv.DictReader(fh, delimiter="\t"))
        if not rows:
            continue
        row = rows[-1]
        jobs.append(
            Job(
                rule=path.parent.name,
                wildcards=path.stem,
                seconds=_number(row, "s"),
                cpu_seconds=_number(row, "cpu_time"),
                max_rss_mb=_number(row, "max_rss"),
                end=path.stat().st_mtime,
            )
        )
    return sorted(jobs, key=lambda j: j.end)


@dataclass(frozen=True)
class RuleTime:
    """One rule's jobs in the last run: how many, their wall and CPU seconds summed, the longest, peak memory."""

    rule: str
    jobs: int
    seconds: float
    longest: float
    cpu_seconds: float
    max_rss_mb: float


def by_rule(jobs: list[Job]) -> list[RuleTime]:
    """Per rule, longest total wall time first."""
    rules: dict[str, list[Job]] = {}
    for j in jobs:
        rules.setdefault(j.rule, []).append(j)
    out = [
        RuleTime(
            rule=r,
            jobs=len(js),
            seconds=sum(j.seconds for j in js),
            longest=max(j.seconds for j in js),
            cpu_seconds=sum(j.cpu_seconds for j in js),
            max_rss_mb=max(j.max_rss_mb for j in js),
        )
        for r, js in rules.items()
    ]
    return sorted(out, key=lambda r: -r.seconds)


PAUSE = 1800.0  # s: no job running for longer than this splits a run into sittings


def sittings(jobs: list[Job], pause: float = PAUSE) -> list[list[Job]]:
    """The jobs in sittings: a run resumed after a pause (a crash, a rerun of some stages on a later day) spans the
    pause too, so its time is each sitting's span, from its first start to its last end, summed."""
    out: list[list[Job]] = []
    last_end = -float("inf")
    for j in sorted(jobs, key=lambda j: j.start):
        if j.start - last_end > pause:
            out.append([])
        out[-1].append(j)
        last_end = max(last_end, j.end)
    return out


def span_seconds(jobs: list[Job]) -> float:
    """The run's time: its sittings' spans summed (:func:`sittings`)."""
    return sum(max(j.end for j in s) - min(j.start for j in s) for s in sittings(jobs))


def alone(jobs: list[Job], cores: int = 2) -> tuple[float, dict[str, float]]:
    """Seconds of the run during which fewer jobs ran than there are ``cores`` (a core idle), and how much of it each
    job ran alone (the jobs the run waited on): (idle core-seconds, {job name: seconds it ran alone})."""
    events = sorted({t for j in jobs for t in (j.start, j.end)})
    idle, by_job = 0.0, {}
    for a, b in zip(events, events[1:], strict=False):
        running = [j for j in jobs if j.start < b and j.end > a]
        if len(running) < cores:
            idle += (cores - len(running)) * (b - a)
        if len(running) == 1:
            by_job[running[0].name] = by_job.get(running[0].name, 0.0) + (b - a)
    return idle, dict(sorted(by_job.items(), key=lambda kv: -kv[1]))


CHAIN_SLACK = 5.0  # s: a job that started within this of another's end is taken to have waited on it


def critical_path(jobs: list[Job], slack: float = CHAIN_SLACK) -> list[Job]:
    """The chain of jobs that set the run's wall time, first to last, read from the times alone: from the job that
    ended last, each step back goes to the job that ended last before this one started (within ``slack``): the
    input it waited on, or the job whose end freed the core it ran on. Shortening a job off this chain does not
    shorten the run."""
    if not jobs:
        return []
    chain = [max(jobs, key=lambda j: j.end)]
    while True:
        start = chain[-1].start
        before = [j for j in jobs if j.end <= start + slack and j not in chain and j.start < start]
        if not before:
            return chain[::-1]
        chain.append(max(before, key=lambda j: j.end))


def markdown(jobs: list[Job]) -> list[str]:
    """The report's section: the run's span, the time per rule, and the jobs that ran alone while a core idled."""
    if not jobs:
        return [
            "## Time per rule",
            "",
            "No per-rule benchmarks were found (`results/benchmarks/`): the workflow's rules write them when they run.",
            "",
        ]
    span = span_seconds(jobs)
    n_sit = len(sittings(jobs))
    cpu = sum(j.cpu_seconds for j in jobs)
    where = f" in {n_sit} sittings (each from its first start to its last end)" if n_sit > 1 else ""
    lines = [
        "## Time per rule",
        "",
        f"The last run's {len(jobs)} jobs (Snakemake's `benchmark:` files in `results/benchmarks/`) span "
        f"{span / 60:.1f} min{where or ' from the first start to the last end'}, {cpu / 60:.1f} CPU min in all.",
        "",
        "| rule | jobs | wall s (all jobs) | longest job s | CPU s | peak MB |",
        "|---|---|---|---|---|---|",
    ]
    for r in by_rule(jobs):
        lines.append(
            f"| {r.rule} | {r.jobs} | {r.seconds:.1f} | {r.longest:.1f} | {r.cpu_seconds:.1f} | {r.max_rss_mb:.0f} |"
        )
    idle, solo = alone(jobs)
    lines += [
        "",
        f"A core stood idle for {idle / 60:.1f} core-min of the run (fewer jobs running than the 2 cores); "
        "the jobs that ran alone longest, what the run waited on:",
        "",
        "| job | s alone |",
        "|---|---|",
    ]
    lines += [f"| {name} | {sec:.1f} |" for name, sec in list(solo.items())[:8]]
    path = critical_path(jobs)
    lines += [
        "",
        f"The critical path, read from the jobs' times (each job after the one it waited on): {len(path)} jobs, "
        f"{sum(j.seconds for j in path) / 60:.1f} min of the run's {span / 60:.1f}:",
        "",
        "| job | started at (min) | s |",
        "|---|---|---|",
    ]
    t0 = min(j.start for j in jobs)
    lines += [f"| {j.name} | {(j.start - t0) / 60:.1f} | {j.seconds:.1f} |" for j in path]
    return lines + [""]


def rule_stages(root: str | Path) -> dict[str, str]:
    """Rule name -> its stage (the rules file it is in, ``workflow/rules/<stage>.smk``) of the workflow at ``root``."""
    out = {}
    for smk in sorted((Path(root) / "workflow" / "rules").glob("*.smk")):
        text = smk.read_text()
        for name in re.findall(r"^(?:rule|checkpoint)\s+(\w+)\s*:", text, re.M):
            out[name] = smk.stem
        # a rule derived from another: ``use rule gap_diagnose as gap_dev_diagnose with:``
        for name in re.findall(r"^use\s+rule\s+\w+\s+as\s+(\w+)", text, re.M):
            out[name] = smk.stem
    return out


def by_stage(jobs: list[Job], stages: dict[str, str]) -> list[dict]:
    """Per stage (``stages``: rule -> stage, :func:`rule_stages`; others ``other``), longest total wall time first:
    its rules, jobs, wall seconds (jobs summed), longest job and CPU seconds."""
    rows: dict[str, list[RuleTime]] = {}
    for r in by_rule(jobs):
        rows.setdefault(stages.get(r.rule, "other"), []).append(r)
    return [
        {
            "stage": stage,
            "rules": [r.rule for r in rs],
            "jobs": sum(r.jobs for r in rs),
            "seconds": sum(r.seconds for r in rs),
            "longest": max(r.longest for r in rs),
            "cpu_seconds": sum(r.cpu_seconds for r in rs),
        }
        for stage, rs in sorted(rows.items(), key=lambda kv: -sum(r.seconds for r in kv[1]))
    ]
