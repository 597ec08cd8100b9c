"""The cluster profile against a real scheduler: a one-node SLURM without accounting, started by the test.

tests/slurm/run_slurm_test.sh does the work (installing slurm-wlm and munge with apt-get
if they are missing, starting and stopping the daemons); this runs it and reports a skip
with the script's reason where the machine cannot host the cluster (not root, no SLURM
and no apt-get). IMPLY_SKIP_SLURM_TEST=1 skips it on purpose.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).with_name("run_slurm_test.sh")
SKIPPED = 77  # the script's exit status for "cannot run here"
# the script limits each of its waits; this covers an install with apt-get and both runs
TIME_LIMIT = 1500


def _cannot_run_here() -> str | None:
    if os.environ.get("IMPLY_SKIP_SLURM_TEST"):
        return "IMPLY_SKIP_SLURM_TEST is set"
    if sys.platform != "linux":
        return "a one-node SLURM needs Linux"
    if os.geteuid() != 0:
        return "starting munged, slurmctld and slurmd needs root"
    if not shutil.which("slurmctld") and not shutil.which("apt-get"):
        return "SLURM is not installed and there is no apt-get to install slurm-wlm and munge"
    return None


@pytest.mark.slow
def test_profile_runs_on_a_real_slurm_without_accounting(tmp_path):
    reason = _cannot_run_here()
    if reason:
        pytest.skip(reason)
    env = {**os.environ, "PYTHON": sys.executable}
    # its own process group, so that on a timeout SIGTERM reaches the script, Snakemake and
    # the daemons alike, and the script's exit trap stops whatever is left
    proc = subprocess.Popen(
        ["bash", str(SCRIPT), str(tmp_path)],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env=env,
        start_new_session=True,
    )
    try:
        out, _ = proc.communicate(timeout=TIME_LIMIT)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            out, _ = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            out, _ = proc.communicate()
        pytest.fail(f"{SCRIPT.name} ran past {TIME_LIMIT} s and was stopped:\n{out[-6000:]}")
    if proc.returncode == SKIPPED:
        pytest.skip(out.strip().splitlines()[-1].removeprefix("SKIP: "))
    print(out)  # the steps, for the record (pytest -s, or shown on failure)
    assert proc.returncode == 0, out[-6000:]
    assert "PASS:" in out and "Nothing to be done" in out
