"""The real-SLURM check (tests/slurm/run_slurm_test.sh), started in the background when the run collects its test.

The script spends most of its 40 to 60 s waiting: on its daemons, and on the SLURM executor's status checks, which
back off by 10 s after each check that finds no job finished. Started by the first test worker to finish collecting,
it waits beside the other tests instead of holding a worker; tests/slurm/test_slurm_profile.py then reads its exit
status and output. Its folder (``slurm-check`` in the run's shared temporary folder) holds the script's work folder,
``out`` (its output) and ``rc`` (its exit status, written last).
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).resolve().parent / "slurm" / "run_slurm_test.sh"
TEST = "tests/slurm/test_slurm_profile.py::"
SKIPPED = 77  # the script's exit status for "cannot run here"
# the script limits each of its waits; this covers an install with apt-get and both runs
TIME_LIMIT = 1500

_started: subprocess.Popen | None = None


def cannot_run_here() -> str | None:
    """Why this machine cannot host the one-node cluster, or None."""
    if os.environ.get("IMPLY_SKIP_SLURM_TEST"):
        return "IMPLY_SKIP_SLURM_TEST is set"
    if sys.platform != "linux":
        return "a one-node SLURM needs Linux"
    if os.geteuid() != 0:
        return "starting munged, slurmctld and slurmd needs root"
    if not shutil.which("slurmctld") and not shutil.which("apt-get"):
        return "SLURM is not installed and there is no apt-get to install slurm-wlm and munge"
    return None


def start(folder: Path) -> None:
    """Start the script in ``folder`` unless a worker of this run already did (or the machine cannot host it)."""
    global _started
    try:
        fd = os.open(folder / "started", os.O_CREAT | os.O_EXCL | os.O_WRONLY)
    except FileExistsError:
        return
    try:
        if cannot_run_here():
            return
        # its own process group, so that at the end SIGTERM reaches the script, Snakemake and the daemons alike
        _started = subprocess.Popen(
            ["bash", "-c", 'bash "$0" "$1" >"$2/out" 2>&1; echo $? >"$2/rc.partial"; mv "$2/rc.partial" "$2/rc"']
            + [str(SCRIPT), str(folder / "work"), str(folder)],
            env={**os.environ, "PYTHON": sys.executable},
            start_new_session=True,
        )
        os.write(fd, str(_started.pid).encode())
    finally:
        os.close(fd)


def finish(interrupted: bool = False) -> None:
    """At the end of the worker's session: wait for a script it started (another worker's test may still read it),
    stopping it past the time limit, or at once where the run was interrupted (Ctrl-C)."""
    if _started is None:
        return
    try:
        _started.wait(timeout=5 if interrupted else TIME_LIMIT)
    except subprocess.TimeoutExpired:
        os.killpg(_started.pid, signal.SIGTERM)
        try:
            _started.wait(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(_started.pid, signal.SIGKILL)
            _started.wait()
