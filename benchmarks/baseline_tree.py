"""Shared by the benchmarks that time this checkout's code against a baseline commit's in the same run."""

from __future__ import annotations

import contextlib
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@contextlib.contextmanager
def baseline_tree(revision: str) -> Iterator[Path]:
    """A detached git worktree of ``revision`` in a temporary folder, removed afterwards."""
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp) / "baseline"
        subprocess.run(
            ["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), revision],
            check=True,
            capture_output=True,
        )
        try:
            yield tree
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=False)


def imply_command(src: Path, *args: str) -> list[str]:
    """``imply ARGS`` run with the package under ``src`` imported ahead of the installed one."""
    return [
        sys.executable,
        "-c",
        "import sys; sys.path.insert(0, sys.argv[1]); import imply; "
        "assert imply.__file__.startswith(sys.argv[1]), imply.__file__; from imply.cli import main; "
        "sys.exit(main(sys.argv[2:]))",
        str(src),
        *args,
    ]


def timed_imply(src: Path, args: list[str], candidates: list[str] | None = None) -> float:
    """Wall seconds of ``imply ARGS`` (with ``--effects`` for a candidate list) under ``src``; exits on failure."""
    cmd = imply_command(src, *args) + (["--effects", ",".join(candidates)] if candidates else [])
    start = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode:
        raise SystemExit(f"imply {' '.join(args[:2])} under {src} failed:\n{proc.stderr[-2000:]}")
    return time.perf_counter() - start


def ab_rounds(repeats: int) -> Iterator[tuple[int, str]]:
    """(round, "baseline" or "current") for ``repeats`` rounds, the order alternating from round to round."""
    for r in range(repeats):
        yield from ((r, which) for which in (("baseline", "current") if r % 2 == 0 else ("current", "baseline")))


def print_medians(times: dict[str, list[float]], revision: str) -> None:
    """The median wall time of each code and their ratio, current over baseline."""
    base, cur = statistics.median(times["baseline"]), statistics.median(times["current"])
    print(f"median: baseline ({revision}) {base:.1f} s, current {cur:.1f} s, ratio {cur / base:.2f}")
