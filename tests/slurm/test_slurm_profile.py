"""The cluster profile against a real scheduler: a one-node SLURM without accounting, started by the test run.

tests/slurm/run_slurm_test.sh does the work (installing slurm-wlm and munge with apt-get if they are missing, starting
and stopping the daemons). The run starts it in the background once its test is collected (tests/slurm_background.py),
so that its waits overlap the other tests; this reads its exit status and output, and reports a skip with the script's
reason where the machine cannot host the cluster (not root, no SLURM and no apt-get). IMPLY_SKIP_SLURM_TEST=1 skips it
on purpose.
"""

from __future__ import annotations

import time

import pytest

from run_folders import pid_file_alive, run_folder
from slurm_background import SKIPPED, TIME_LIMIT, cannot_run_here, start


@pytest.mark.slow
def test_profile_runs_on_a_real_slurm_without_accounting(tmp_path_factory):
    reason = cannot_run_here()
    if reason:
        pytest.skip(reason)
    folder = run_folder(tmp_path_factory, "slurm-check")
    start(folder)  # started already where the run collected this test; here when it did not
    rc, deadline = folder / "rc", time.monotonic() + TIME_LIMIT + 120
    while not rc.exists():
        assert time.monotonic() < deadline, f"the SLURM check ran past {TIME_LIMIT} s: {folder / 'out'}"
        # the pid is written right after the start: an empty file is a start under way; the status is written just
        # before the script's shell ends
        alive = pid_file_alive(folder / "started")
        assert alive or rc.exists(), f"the SLURM check stopped without its status: {folder}"
        time.sleep(0.5)
    code, out = int(rc.read_text()), (folder / "out").read_text()
    if code == SKIPPED:
        pytest.skip(out.strip().splitlines()[-1].removeprefix("SKIP: "))
    print(out)  # the steps, for the record (pytest -s, or shown on failure)
    assert code == 0, out[-6000:]
    assert "PASS:" in out and "Nothing to be done" in out
