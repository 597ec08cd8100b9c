"""Running the workflow on a copy of the repository's Snakefile and config in a temp folder."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def copy_workflow(dest: Path) -> Path:
    """Copy Snakefile, workflow/, envs/ and config.yaml into ``dest`` and return it.

    envs/ is needed even without --use-conda: Snakemake records each rule's conda file.
    """
    dest.mkdir(parents=True, exist_ok=True)
    shutil.copy(ROOT / "Snakefile", dest / "Snakefile")
    shutil.copy(ROOT / "config.yaml", dest / "config.yaml")
    shutil.copytree(ROOT / "workflow", dest / "workflow")
    shutil.copytree(ROOT / "envs", dest / "envs")
    return dest


def snakemake_command() -> list[str]:
    """``snakemake`` as this interpreter's installation runs it: through the test worker's fork server where the test
    asked for it (the ``forked_imply`` fixture puts its clients first on PATH), else ``python -m snakemake``."""
    if os.environ.get("IMPLY_FORKSERVER"):
        return [shutil.which("snakemake") or "snakemake"]
    return [sys.executable, "-m", "snakemake"]


def plant_table(workdir: Path, table: Path) -> None:
    """Put the tests' tiny table (the ``tiny_table_path`` fixture) where the table rule writes it, so that a run on a
    tiny config reads it instead of building it again (the table rule is run by tests/workflow/test_table_workflow.py;
    a test there holds the tiny configs to the planted table's settings)."""
    (workdir / "results" / "table").mkdir(parents=True, exist_ok=True)
    shutil.copy(table, workdir / "results" / "table" / "table.npz")


def snakemake(
    workdir: Path, *args: str, check: bool = True, timeout: float | None = None
) -> subprocess.CompletedProcess:
    """Run snakemake in ``workdir`` with the current interpreter's installation (:func:`snakemake_command`).

    Put targets before ``--configfile``: that option takes every value after it.
    """
    cmd = [
        *snakemake_command(),
        "--cores",
        "2",
        "--directory",
        str(workdir),
        "--snakefile",
        str(workdir / "Snakefile"),
        *args,
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True, cwd=workdir, timeout=timeout)
    if check and proc.returncode != 0:
        raise AssertionError(f"snakemake failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return proc


def planned(proc: subprocess.CompletedProcess) -> set[str]:
    """The rules a dry run (``-n``) plans, from its "rule NAME:" lines."""
    return {line.split()[1].rstrip(":") for line in proc.stdout.splitlines() if line.startswith("rule ")}
