"""A fork server for the workflow tests' ``snakemake`` runs and their ``imply`` jobs.

A workflow test runs Snakemake and its rules' shell commands as written, each ``imply ...`` a process of its own.
Most of such a process's time on the tests' tiny configs is its start: importing NumPy, SciPy, pandas, MuJoCo and
PyTorch takes 2 to 5 CPU-seconds, Snakemake's imports and plugin search about 3, the job's work often less. The server
imports them once; every ``imply`` the rules start, and every ``snakemake`` the test starts, then runs in a fork of
it: ``bin/imply`` and ``bin/snakemake`` (written by :func:`write_clients`; ``bin`` first on the PATH of the test's
Snakemake) hand the server their program, arguments, working folder, environment and standard input, output and
error, and exit with the fork's exit status, forwarding SIGINT and SIGTERM to it; the fork takes them as the client's
own process would (ignored only where the client was started with them ignored), and a client killed hard takes its
fork with it. Where the server cannot be reached a client runs the real program instead.

    python tests/forkserver.py SOCKET      # serve until stopped
"""

from __future__ import annotations

import importlib
import json
import os
import pkgutil
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
    "snakemake.cli",
    "snakemake.api",
    "snakemake.workflow",
    "snakemake.scheduling.job_scheduler",
    # imported on first use: the optimizer's first step (torch._dynamo, with SymPy), Parquet files, PDF figures and
    # their fonts, the workflow's config check (jsonschema), Snakemake's storage plugins (boto3, requests,
    # smart_open), the diagnosis's corrected scene (mujoco.sysid); each command's module is imported by serve()
    "torch._dynamo",
    "pyarrow.parquet",
    "pandas.io.parquet",
    "matplotlib.backends.backend_agg",
    "matplotlib.backends.backend_pdf",
    "fontTools.subset",
    "jsonschema",
    "boto3",
    "requests",
    "smart_open",
    "snakemake.storage",
    "mujoco.sysid",
    "imply.config_check",
    "imply.kernels",
    "imply.paper.figures",
    "imply.results",
    "imply.readout",
)
# the program a client names, and the module that runs it as its console script would
PROGRAMS = {"imply": "imply.cli", "snakemake": "snakemake"}
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
    import imply.cli

    # each command's module, as a job first imports it (not __main__, which would run the command line)
    for command in pkgutil.iter_modules(imply.cli.__path__):
        if command.name.startswith("_"):
            continue
        try:
            importlib.import_module(f"imply.cli.{command.name}")
        except ImportError:
            pass
    try:  # Snakemake's plugin search (its command line's options): once here, not in every run
        from snakemake.cli import get_argument_parser

        get_argument_parser()
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
    """SIGCHLD: collect every fork that has ended (their exit status went to their clients already)."""
    try:
        while os.waitpid(-1, os.WNOHANG)[0]:
            pass
    except ChildProcessError:
        pass


def _run_job(conn: socket.socket) -> None:
    """In the fork: take the client's request and standard streams, run its program (``imply`` or ``snakemake``) as
    the program's console script would, and send the client the exit status."""
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
        # Ctrl-C and SIGTERM as the client's own process would take them, whatever the server was started with
        ignored = set(request["ignored"])
        signal.signal(signal.SIGINT, signal.SIG_IGN if signal.SIGINT in ignored else signal.default_int_handler)
        signal.signal(signal.SIGTERM, signal.SIG_IGN if signal.SIGTERM in ignored else signal.SIG_DFL)
        program = request["program"]
        sys.argv = [program, *request["argv"]]
        conn.send(json.dumps({"pid": os.getpid()}).encode())
        # a client killed hard (SIGKILL, as a test or a crash would) takes its job with it, as it would its own child
        threading.Thread(target=_die_with_client, args=(conn,), daemon=True).start()
        if program == "snakemake":
            from snakemake.cli import main as snakemake_main

            snakemake_main(request["argv"])
        else:
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
except OSError:  # no server: the real program
    os.execv({python!r}, [{python!r}, "-m", {module!r}, *argv])
# the signals this process was started with ignored (a shell starts its background jobs so): the job ignores them too
ignored = [int(s) for s in (signal.SIGINT, signal.SIGTERM) if signal.getsignal(s) == signal.SIG_IGN]
request = {{"program": {program!r}, "argv": argv, "cwd": os.getcwd(), "env": dict(os.environ), "ignored": ignored}}
socket.send_fds(conn, [json.dumps(request).encode()], [0, 1, 2])
pid = json.loads(conn.recv(4096))["pid"]
for sig in (signal.SIGINT, signal.SIGTERM):
    signal.signal(sig, lambda number, frame: os.kill(pid, number))
answer = conn.recv(4096)
sys.exit(json.loads(answer)["exit"] if answer else 1)
"""


def write_clients(folder: Path) -> Path:
    """Write ``folder/imply`` and ``folder/snakemake``, clients that run their program in the server (or the real
    one without a server); return ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    for program, module in PROGRAMS.items():
        client = folder / program
        code = CLIENT.format(python=sys.executable, module=module, program=program)
        client.write_text(f"#!{sys.executable} -S\n" + textwrap.dedent(code))
        client.chmod(0o755)
    return folder


if __name__ == "__main__":
    serve(sys.argv[1])
