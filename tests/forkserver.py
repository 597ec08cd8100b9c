"""A fork server for the workflow tests' ``imply`` jobs.

A workflow test runs its rules' shell commands as written, each ``imply ...`` a process of its own. Most of such a
process's time on the tests' tiny configs is its start: importing NumPy, SciPy, pandas, MuJoCo and PyTorch takes 2 to
5 CPU-seconds, the job's work often less. The server imports them once; every ``imply`` the rules start then runs in
a fork of it: ``bin/imply`` (written by :func:`write_client`, first on the PATH of the test's Snakemake) hands the
server its arguments, working folder, environment and its standard input, output and error, and exits with the
fork's exit status, forwarding SIGINT and SIGTERM to it. Where the server cannot be reached the client runs the
real ``imply`` instead.

    python tests/forkserver.py SOCKET      # serve until stopped
"""

from __future__ import annotations

import importlib
import json
import os
import signal
import socket
import sys
import textwrap
import threading
from pathlib import Path

# what the jobs import, heaviest first; a module missing here (an extra not installed) is skipped
PRELOAD = (
    "torch",
    "scipy.optimize",
    "scipy.interpolate",
    "scipy.stats",
    "pandas",
    "mujoco",
    "sklearn.linear_model",
    "matplotlib.pyplot",
    "imply.cli",
    "imply.io",
    "imply.table",
    "imply.score",
    "imply.diagnose.run",
    "imply.diagnose.analysis",
    "imply.realworld.cases",
    "imply.realworld.contact",
    "imply.realworld.lab",
    "imply.evaluate.suite",
    "imply.models.train",
    "imply.models.encoder",
)
MESSAGE_LIMIT = 1 << 20


def serve(path: str) -> None:
    """Import :data:`PRELOAD`, then answer each connection on the Unix socket ``path`` with a fork that runs it."""
    parent = os.getppid()
    os.environ.setdefault("MPLBACKEND", "Agg")
    for name in PRELOAD:
        try:
            importlib.import_module(name)
        except ImportError:
            pass
    # each finished fork reaped here, so that its CPU time counts in the server's (and a timing of the test run's)
    signal.signal(signal.SIGCHLD, _reap)
    server = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    partial = f"{path}.{os.getpid()}.partial"
    server.bind(partial)
    server.listen(64)
    os.replace(partial, path)  # the socket appears once it takes connections
    sys.stdout.flush()
    sys.stderr.flush()
    server.settimeout(2.0)
    while True:
        try:
            conn, _ = server.accept()
        except TimeoutError:
            if os.getppid() != parent:  # the test run that started the server is gone: so is the server
                return
            continue
        if os.fork() == 0:
            server.close()
            conn.settimeout(None)
            _run_job(conn)  # never returns
        conn.close()


def _reap(signum, frame) -> None:
    try:
        while os.waitpid(-1, os.WNOHANG)[0]:
            pass
    except ChildProcessError:
        pass


def _run_job(conn: socket.socket) -> None:
    """In the fork: take the client's request and standard streams, run ``imply`` as its console script would."""
    signal.signal(signal.SIGCHLD, signal.SIG_DFL)
    code = 1
    try:
        message, fds, _, _ = socket.recv_fds(conn, MESSAGE_LIMIT, 3)
        request = json.loads(message)
        for target, fd in zip((0, 1, 2), fds, strict=True):
            os.dup2(fd, target)
            os.close(fd)
        os.chdir(request["cwd"])
        os.environ.clear()
        os.environ.update(request["env"])
        sys.argv = ["imply", *request["argv"]]
        conn.send(json.dumps({"pid": os.getpid()}).encode())
        # a client killed hard (SIGKILL, as a test or a crash would) takes its job with it, as it would its own child
        threading.Thread(target=_die_with_client, args=(conn,), daemon=True).start()
        from imply.cli import main

        code = main()
    except SystemExit as exc:
        if exc.code is None or isinstance(exc.code, int):
            code = exc.code or 0
        else:
            print(exc.code, file=sys.stderr)
    except BaseException:  # noqa: BLE001 - what the interpreter would print, then its exit status
        import traceback

        traceback.print_exc()
        code = 130 if sys.exc_info()[0] is KeyboardInterrupt else 1
    finally:
        import logging

        logging.shutdown()
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        try:
            conn.send(json.dumps({"exit": int(code)}).encode())
        except OSError:
            pass
        os._exit(int(code) & 0xFF)


def _die_with_client(conn: socket.socket) -> None:
    """Wait for the client's end of the connection to close (it only closes when the client is gone), then stop."""
    try:
        conn.recv(1)
    except OSError:
        pass
    os.kill(os.getpid(), signal.SIGKILL)


CLIENT = """\
import json, os, signal, socket, sys
argv = sys.argv[1:]
path = os.environ.get("IMPLY_FORKSERVER", "")
try:
    conn = socket.socket(socket.AF_UNIX, socket.SOCK_SEQPACKET)
    conn.connect(path)
except OSError:  # no server: the real console script
    os.execv({python!r}, [{python!r}, "-m", "imply.cli", *argv])
request = {{"argv": argv, "cwd": os.getcwd(), "env": dict(os.environ)}}
socket.send_fds(conn, [json.dumps(request).encode()], [0, 1, 2])
pid = json.loads(conn.recv(4096))["pid"]
for sig in (signal.SIGINT, signal.SIGTERM):
    signal.signal(sig, lambda number, frame: os.kill(pid, number))
answer = conn.recv(4096)
sys.exit(json.loads(answer)["exit"] if answer else 1)
"""


def write_client(folder: Path) -> Path:
    """Write ``folder/imply``, the client that runs a command in the server (or the real ``imply`` without one)."""
    folder.mkdir(parents=True, exist_ok=True)
    client = folder / "imply"
    client.write_text(f"#!{sys.executable} -S\n" + textwrap.dedent(CLIENT.format(python=sys.executable)))
    client.chmod(0o755)
    return client


if __name__ == "__main__":
    serve(sys.argv[1])
