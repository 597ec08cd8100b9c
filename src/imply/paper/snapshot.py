"""A snapshot of one study run, committed with the documentation: real results before anything has run.

``imply study paper snapshot`` (the workflow's ``snapshot`` rule) copies what the documentation
shows from a finished run's ``results/`` into ``docs/snapshot/`` (paths kept, under
``docs/snapshot/results/``): the reproduction report and ``numbers.json``, the stand-ins'
known answers, every figure a documentation page names in a ``{{ figure ... }}``
placeholder, and each stage's times (the benchmark files' wall and CPU seconds, which a
git checkout cannot keep as file times). It stamps them in ``docs/snapshot/snapshot.json``:
the commit whose code made the results, the date, the machine (CPU model, the widest
vector instruction set it has, the numerical kernels the run pinned), the run's wall time
(from the first job's start to the last job's end) and the claims that hold.

The site shows the snapshot wherever ``results/`` lacks a file, labelled with its commit
and machine (:mod:`imply.docs_pages`). A snapshot is stale when the study code at HEAD
reports other numbers than the snapshot holds (a test compares ``numbers.json``'s names with
the registry's); refresh it with ``snakemake --cores 2 snapshot`` after a run.
"""

from __future__ import annotations

import json
import os
import platform
import re
import shutil
import subprocess
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from imply.io import write_json, write_text
from imply.results import claim_tally

SNAPSHOT_DIR = Path("docs") / "snapshot"
STAMP = "snapshot.json"
# results the documentation reads besides the figures its pages name
FILES = ("results/paper/reproduction.md", "results/paper/numbers.json", "results/evaluate/standins.json")
_FIGURE = re.compile(r"\{\{\s*figure\s+(results/[^|}\s]+)")
README_START, README_END = "<!-- snapshot -->", "<!-- /snapshot -->"


def figure_paths(docs_dir: Path) -> list[str]:
    """Every ``results/...`` path a page under ``docs_dir`` names in a figure placeholder."""
    out: set[str] = set()
    for page in sorted(docs_dir.rglob("*.md")):
        if SNAPSHOT_DIR.name in page.parts:
            continue
        out.update(_FIGURE.findall(page.read_text()))
    return sorted(out)


def machine(kernels: str | None = None) -> dict[str, Any]:
    """The CPU model, the widest of AVX-512 / AVX2 it has, its logical cores, and the kernels the run pinned."""
    model, flags = platform.processor() or platform.machine(), set()
    try:
        text = Path("/proc/cpuinfo").read_text()
        found = re.search(r"^model name\s*:\s*(.+)$", text, re.M)
        model = found.group(1).strip() if found else model
        found = re.search(r"^flags\s*:\s*(.+)$", text, re.M)
        flags = set(found.group(1).split()) if found else set()
    except OSError:
        pass
    isa = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "neither AVX2 nor AVX-512"
    return {"cpu": model, "instruction_set": isa, "cores": os.cpu_count(), "kernels": kernels}


def _commit(root: Path) -> str | None:
    try:
        run = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True, check=True)
    except (OSError, subprocess.CalledProcessError):
        return None
    return run.stdout.strip()


def _claims(parts: Path) -> dict[str, dict[str, int]]:
    """The parts' claims that hold, the paper's and this project's targets apart (:func:`imply.results.claim_tally`)."""
    pairs = []
    for path in sorted(parts.glob("*.json")):
        part = json.loads(path.read_text())
        pairs += [(part["stage"], c) for c in part.get("claims", [])]
    return claim_tally(pairs)


def claims_sentence(stamp: dict) -> str:
    """How many claims hold in a snapshot: the paper's and this project's own targets, each over its own count (a
    stamp from before the two were told apart gives one count)."""
    c = stamp["claims"]
    if "paper" not in c:
        return f"{c['hold']} of its {c['checked']} claims hold"
    paper, ours = c["paper"], c["project"]
    return (
        f"{paper['hold']} of the paper's {paper['checked']} claims hold; "
        f"{ours['hold']} of this project's {ours['checked']} own targets (the gap benchmarks, the evaluate checks, "
        "the pixel model, the Section 5 stand-in's per-seed bar) hold"
    )


# the rules file of the development sets' rules (the gap_development target), timed apart from the default run
DEVELOPMENT_STAGE = "development"


def _benchmark_jobs(root: Path) -> tuple[dict[str, str], list, list]:
    """(rule -> stage, the default run's jobs, the development target's jobs) from the benchmark files."""
    from imply.paper.timings import read_benchmarks, rule_stages

    stages = rule_stages(root)
    jobs = read_benchmarks(root / "results" / "benchmarks")

    def developing(job) -> bool:
        # the lab benchmark's rules run both sets; a development set's job is named by its wildcards
        return stages.get(job.rule) == DEVELOPMENT_STAGE or job.wildcards.startswith("development")

    return stages, [j for j in jobs if not developing(j)], [j for j in jobs if developing(j)]


def development_times(root: Path, split: tuple | None = None) -> dict[str, Any] | None:
    """The gap_development target's jobs, span (first start to last end) and CPU seconds; None where it has not
    run (``split``: :func:`_benchmark_jobs` of ``root``, where the caller has read it)."""
    from imply.paper.timings import span_seconds

    _, _, jobs = split or _benchmark_jobs(root)
    if not jobs:
        return None
    return {"jobs": len(jobs), "wall_seconds": span_seconds(jobs), "cpu_seconds": sum(j.cpu_seconds for j in jobs)}


def stage_times(root: Path, split: tuple | None = None) -> dict[str, Any]:
    """Each stage's rules, jobs, wall seconds (jobs summed), longest job and CPU seconds, and the run's span: the
    default run's jobs only (the development target is timed by :func:`development_times`; ``split`` as there)."""
    from imply.paper.timings import by_stage, sittings, span_seconds

    stages, jobs, _ = split or _benchmark_jobs(root)
    if not jobs:
        return {"jobs": 0, "stages": [], "wall_seconds": None}
    table = by_stage(jobs, stages)

    def day(t: float) -> str:
        return datetime.fromtimestamp(t, UTC).strftime("%Y-%m-%d %H:%M")

    return {
        "jobs": len(jobs),
        "stages": table,
        "wall_seconds": span_seconds(jobs),
        "ended": datetime.fromtimestamp(max(j.end for j in jobs), UTC).strftime("%Y-%m-%d"),
        # a run resumed after a pause: each sitting's span and the stages whose jobs ran in it
        "sittings": [
            {
                "start": day(min(j.start for j in s)),
                "end": day(max(j.end for j in s)),
                "jobs": len(s),
                "stages": sorted({stages.get(j.rule, "other") for j in s}),
            }
            for s in sittings(jobs)
        ],
    }


def write_snapshot(root: Path, out: Path, *, commit: str | None = None, kernels: str | None = None) -> dict:
    """Copy what the documentation shows from ``root/results`` into ``out`` and stamp it (``out/snapshot.json``);
    fill the README's snapshot line. Returns the stamp. FileNotFoundError naming a missing result."""
    root, out = Path(root), Path(out)
    wanted = [*FILES, *figure_paths(root / "docs")]
    missing = [p for p in wanted if not (root / p).is_file()]
    if missing:
        raise FileNotFoundError(f"the run lacks {', '.join(missing)}: run `snakemake --cores 2` first")
    if (out / "results").exists():
        shutil.rmtree(out / "results")
    for rel in wanted:
        (out / rel).parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(root / rel, out / rel)
    numbers = json.loads((root / "results/paper/numbers.json").read_text())
    split = _benchmark_jobs(root)  # the benchmark files, read once for both timings
    times = stage_times(root, split)
    stamp = {
        "commit": commit or _commit(root),
        "date": times.get("ended") or datetime.now(UTC).strftime("%Y-%m-%d"),
        "machine": machine(kernels),
        "wall_seconds": times["wall_seconds"],
        "claims": _claims(root / "results/paper/parts"),
        "numbers": sorted(numbers),
        "stage_times": times,
        "development": development_times(root, split),
        "files": wanted,
    }
    write_json(out / STAMP, stamp)
    readme = root / "README.md"
    if readme.is_file() and README_START in readme.read_text():
        write_text(readme, fill_readme(readme.read_text(), stamp))
    return stamp


def read_stamp(snapshot: Path) -> dict | None:
    """The stamp of the snapshot folder ``snapshot`` (None where there is none)."""
    path = Path(snapshot) / STAMP
    return json.loads(path.read_text()) if path.is_file() else None


def cpu_minutes(stamp: dict) -> float | None:
    """The run's jobs' CPU time summed (minutes): what the run cost, whatever else the machine was doing."""
    stages = (stamp.get("stage_times") or {}).get("stages") or []
    total = sum(float(row.get("cpu_seconds") or 0.0) for row in stages)
    return total / 60 if total else None


def timing(stamp: dict) -> str:
    """How long the run took: from its first job to its last, and its jobs' CPU time ("" where not recorded)."""
    wall = stamp.get("wall_seconds")
    if not wall:
        return ""
    cpu = cpu_minutes(stamp)
    n_sit = len((stamp.get("stage_times") or {}).get("sittings") or [None])
    text = f"{wall / 60:.0f} min from the first job to the last on {stamp['machine']['cores']} cores"
    if n_sit > 1:
        text = (
            f"{wall / 60:.0f} min on {stamp['machine']['cores']} cores in {n_sit} sittings (each from its first job "
            "to its last)"
        )
    return text + (f", {cpu:.0f} CPU-min of jobs" if cpu else "")


# how a snapshot's line names the run's kernel pin (config kernels.pin)
KERNEL_WORDS = {
    "avx2": "every library pinned to AVX2",
    "numpy-avx2": "NumPy pinned to AVX2, PyTorch the machine's own",
    "native": "the machine's own",
}


def label(stamp: dict) -> str:
    """One line naming a snapshot's run: commit, date, machine, time."""
    m = stamp["machine"]
    took = timing(stamp)
    return (
        f"commit {(stamp.get('commit') or 'unknown')[:7]}, run on {stamp['date']} on an {m['cpu']} "
        f"({m['instruction_set']}; kernels: {KERNEL_WORDS.get(m.get('kernels'), m.get('kernels') or 'the default')})"
        + (f", {took}" if took else "")
    )


def readme_line(stamp: dict) -> str:
    """The README's line on the last snapshot: its time and how many claims hold."""
    return f"The last snapshot of the study in the docs ({label(stamp)}): {claims_sentence(stamp)}."


def fill_readme(text: str, stamp: dict) -> str:
    """``text`` with the part between the snapshot markers replaced by :func:`readme_line`."""
    start, end = text.index(README_START) + len(README_START), text.index(README_END)
    return text[:start] + "\n" + readme_line(stamp) + "\n" + text[end:]
