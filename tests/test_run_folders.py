"""The folders the test workers share, and what is built in them once for all workers."""

from __future__ import annotations

import shutil

import pytest

import run_folders


class _Factory:
    """What ``built_once`` reads of pytest's ``tmp_path_factory``: a worker's base folder."""

    def __init__(self, base):
        self.base = base

    def getbasetemp(self):
        return self.base


def test_a_build_after_a_dead_worker_clears_its_leftovers_while_another_worker_creates_the_folder(
    tmp_path, monkeypatch
):
    """A worker that died while building left files behind; the next one clears them and builds, though another worker's
    ``run_folder`` creates the shared folder again in the middle of that (seen: the build failed with FileExistsError,
    and with it every test that needed the tiny table)."""
    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw0")
    shared = tmp_path / "thing"
    (shared / "partial").mkdir(parents=True)
    (shared / "partial" / "half.npz").write_text("half")
    (shared / "stale.txt").write_text("stale")
    real_rmtree = shutil.rmtree

    def rmtree_then_other_worker_arrives(path, *args, **kwargs):
        real_rmtree(path, *args, **kwargs)
        run_folders.run_folder(_Factory(tmp_path / "gw1"), "thing")

    monkeypatch.setattr(run_folders.shutil, "rmtree", rmtree_then_other_worker_arrives)
    builds = []

    def build(folder):
        builds.append(sorted(p.name for p in folder.iterdir()))
        (folder / "thing.txt").write_text("built")

    folder = run_folders.built_once(_Factory(tmp_path / "gw0"), "thing", build)
    assert folder == shared
    assert builds == [[]]
    assert (folder / "thing.txt").read_text() == "built"
    assert (folder / ".built").exists() and not (tmp_path / "thing.lock").exists()
    # built: a second worker takes it as it is
    assert run_folders.built_once(_Factory(tmp_path / "gw1"), "thing", lambda f: pytest.fail("built twice")) == shared


def test_a_failed_build_fails_the_workers_that_wait_for_it_with_its_error(tmp_path, monkeypatch):
    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw0")

    def broken(folder):
        raise ValueError("no table today")

    with pytest.raises(ValueError, match="no table today"):
        run_folders.built_once(_Factory(tmp_path / "gw0"), "thing", broken)
    with pytest.raises(pytest.fail.Exception, match="ValueError: no table today"):
        run_folders.built_once(_Factory(tmp_path / "gw1"), "thing", lambda f: pytest.fail("built after a failure"))
