"""Folders shared by a test run's xdist workers, and things built in them once for all workers."""

from __future__ import annotations

import os
import shutil
import time
from pathlib import Path

import pytest


def built_once(tmp_path_factory, name: str, build) -> Path:
    """A folder named ``name`` shared by the run's test workers, filled by ``build(folder)`` in whichever worker asks
    first; the others wait for it instead of building it again (a module fixture is otherwise built once per worker
    that runs one of the module's tests). A failed build fails every worker that waits for it, with its error."""
    folder = run_folder(tmp_path_factory, name)
    done, failed, lock = folder / ".built", folder / ".failed", folder.with_name(f"{name}.lock")
    while not done.exists():
        if failed.exists():
            pytest.fail(f"building {name} failed in another test worker: {failed.read_text()}")
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            if not pid_file_alive(lock):  # a worker that died while building
                lock.unlink(missing_ok=True)
            time.sleep(0.5)
            continue
        os.write(fd, str(os.getpid()).encode())
        try:
            if done.exists():  # built by the worker that held the lock a moment ago
                return folder
            # what a worker that died while building left behind; the folder itself stays, for another worker's
            # run_folder may create it again at any moment
            _empty(folder)
            build(folder)
            done.touch()
        except BaseException as exc:
            failed.write_text(f"{type(exc).__name__}: {exc}"[:3000])
            raise
        finally:
            os.close(fd)
            lock.unlink(missing_ok=True)
    return folder


def _empty(folder: Path) -> None:
    """Remove what ``folder`` holds, keeping the folder."""
    for entry in folder.iterdir():
        if entry.is_dir() and not entry.is_symlink():
            shutil.rmtree(entry)
        else:
            entry.unlink()


def pid_file_alive(pid_file: Path) -> bool:
    """Whether the process whose pid ``pid_file`` holds still runs (a file just created, still empty, counts)."""
    try:
        text = pid_file.read_text().strip()
    except FileNotFoundError:
        return True
    if not text:
        return True
    try:
        os.kill(int(text), 0)
    except ProcessLookupError:
        return False
    except (PermissionError, ValueError):
        return True
    return True


def run_folder(tmp_path_factory, name: str) -> Path:
    """A folder named ``name`` for this test run, shared by its xdist workers (their base folders' parent), or a
    fresh one without xdist."""
    if not os.environ.get("PYTEST_XDIST_WORKER"):
        return tmp_path_factory.mktemp(name)
    folder = tmp_path_factory.getbasetemp().parent / name
    folder.mkdir(exist_ok=True)
    return folder


def copy_whole(source: Path, target: Path) -> None:
    """Copy a file so that a reader never sees it half-written (a temporary name, then a rename)."""
    partial = target.with_name(f".{target.name}.{os.getpid()}.partial")
    shutil.copyfile(source, partial)
    partial.replace(target)
