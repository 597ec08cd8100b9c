"""The workflow tests' fork server (tests/forkserver.py) runs ``imply`` as the console script does: the same output,
exit status, working folder and environment; and without a server the client runs the console script itself."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time

import pytest

from imply import __version__


def _imply(env: dict, *argv: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run(["imply", *argv], capture_output=True, text=True, env=env, cwd=cwd, timeout=120)


@pytest.fixture
def server_env(imply_server) -> dict:
    return {**os.environ, **imply_server}


def test_the_client_answers_as_the_console_script_does(server_env):
    client_folder = server_env["PATH"].split(os.pathsep)[0]
    assert shutil.which("imply", path=server_env["PATH"]) == os.path.join(client_folder, "imply")
    version = _imply(server_env, "--version")
    assert version.returncode == 0 and version.stdout.strip() == f"imply {__version__}"
    bad = _imply(server_env, "score", "no-such-file.csv", "--table", "no-such-table.npz")
    plain = subprocess.run(["imply", "score", "no-such-file.csv", "--table", "no-such-table.npz"], capture_output=True)
    assert bad.returncode == plain.returncode == 2
    assert bad.stderr.encode() == plain.stderr and bad.stderr.count("\n") == 1


def test_a_job_runs_in_the_clients_folder_with_its_environment(server_env, tmp_path, analytic_table):
    """Relative paths are the client's folder's, and the job reads the client's environment (here its log level)."""
    analytic_table.save(tmp_path / "table.npz")
    (tmp_path / "pushes.csv").write_text("object_id,speed,mass,friction\na,0.3,0.5,0.2\nb,0.7,1.0,0.35\n")
    done = _imply(server_env, "sim", "pushes", "pushes.csv", "-o", "log.csv", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert (tmp_path / "log.csv").read_text().startswith("object_id,")
    without = {k: v for k, v in server_env.items() if k != "IMPLY_FORKSERVER"}
    plain = _imply(without, "sim", "pushes", "pushes.csv", "-o", "plain.csv", cwd=tmp_path)
    assert plain.returncode == 0 and (tmp_path / "plain.csv").read_text() == (tmp_path / "log.csv").read_text()


def _start_long_job(server_env: dict, tmp_path, sigint=signal.SIG_DFL) -> subprocess.Popen:
    """A client whose job (a table of many cells) runs for longer than the test waits, started with ``sigint`` as its
    SIGINT disposition; returns once the server's fork runs the job."""
    axis = '{"min": 0.2, "max": 1.0, "n": 40}'
    grid = f'{{"speeds": {axis}, "masses": {axis}, "frictions": {axis}}}'
    client = subprocess.Popen(
        ["imply", "table", "build", "--grid-json", grid, "--threads", "1", "-o", str(tmp_path / "t.npz")],
        env=server_env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, sigint),
    )
    sock = server_env["IMPLY_FORKSERVER"]
    deadline = time.monotonic() + 60
    while not _forks_running(sock) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _forks_running(sock), "the job never started"
    time.sleep(1.0)
    assert client.poll() is None, client.stderr.read()  # still building
    return client


def _wait_for_no_forks(sock: str) -> None:
    deadline = time.monotonic() + 30
    while _forks_running(sock) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _forks_running(sock)


def test_a_client_killed_hard_takes_its_job_with_it(server_env, tmp_path):
    """SIGKILL to the client (as to a job's process group) stops the fork that runs its command."""
    client = _start_long_job(server_env, tmp_path)
    client.send_signal(signal.SIGKILL)
    client.wait()
    _wait_for_no_forks(server_env["IMPLY_FORKSERVER"])
    assert not (tmp_path / "t.npz").exists()


@pytest.mark.parametrize("sigint", [signal.SIG_DFL, signal.SIG_IGN], ids=["default", "ignored"])
def test_ctrl_c_reaches_the_job_as_it_would_the_console_script(server_env, tmp_path, sigint):
    """SIGINT to the client stops its job as it would the console script, with the console script's message and
    status, where the client was started with SIGINT at its default; and the job carries on where the client was
    started with SIGINT ignored (as a shell starts a background job), whichever the server itself was started with."""
    client = _start_long_job(server_env, tmp_path, sigint)
    try:
        client.send_signal(signal.SIGINT)
        if sigint == signal.SIG_IGN:
            time.sleep(1.0)
            assert client.poll() is None, client.stderr.read()
            client.send_signal(signal.SIGKILL)
        _, err = client.communicate(timeout=60)
    finally:
        if client.poll() is None:  # the job took no notice: stop it, and its fork with it
            client.kill()
            client.wait()
    if sigint == signal.SIG_DFL:
        assert client.returncode == 130 and err.strip().endswith("imply table build: interrupted"), err
    _wait_for_no_forks(server_env["IMPLY_FORKSERVER"])
    assert not (tmp_path / "t.npz").exists()


def _forks_running(sock: str) -> list[int]:
    """The server's forks that run a job: live processes with the server's command line (the socket's path in it),
    the server itself left out."""
    found = []
    for entry in os.scandir("/proc"):
        if not entry.name.isdigit():
            continue
        try:
            with open(f"/proc/{entry.name}/cmdline", "rb") as fh:
                cmdline = fh.read()
            with open(f"/proc/{entry.name}/stat") as fh:
                state = fh.read().rsplit(")", 1)[1].split()[0]
        except OSError:
            continue
        if sock.encode() in cmdline and state != "Z":
            found.append(int(entry.name))
    return sorted(found)[1:]  # the server started first: the lowest pid (pids do not wrap in a test's time)
