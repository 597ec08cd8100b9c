"""Shared by the benchmarks that time this checkout's code against a baseline commit's in the same run."""

from __future__ import annotations

import contextlib
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@contextlib.contextmanager
def baseline_tree(revision: str) -> Iterator[Path]:
    """A detached git worktree of ``revision`` in a temporary folder, removed afterwards."""
    with tempfile.TemporaryDirectory() as tmp:
        tree = Path(tmp) / "baseline"
        subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), revision], check=True,
                       capture_output=True)  # fmt: skip
        try:
            yield tree
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)], check=False)


def imply_command(src: Path, *args: str) -> list[str]:
    """``imply ARGS`` run with the package under ``src`` imported ahead of the installed one."""
    return [sys.executable, "-c", "import sys; sys.path.insert(0, sys.argv[1]); import imply; "
            "assert imply.__file__.startswith(sys.argv[1]), imply.__file__; from imply.cli import main; "
            "sys.exit(main(sys.argv[2:]))", str(src), *args]  # fmt: skip
