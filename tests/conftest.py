"""Shared fixtures: a tiny table (seconds), the full default table (built once per run), and evaluation suites."""

from __future__ import annotations

import json
import os

# before mujoco is imported anywhere: offscreen rendering through EGL
os.environ.setdefault("MUJOCO_GL", "egl")
from pathlib import Path

import numpy as np
import pytest
import yaml

from imply.sim import SceneConfig
from imply.table import PushTable, TableGrid
from run_folders import built_once, copy_whole, run_folder

ROOT = Path(__file__).resolve().parents[1]


# The longest test first: --dist worksteal hands the first half of the list to one worker and the second half to the
# other, and a worker out of work takes tests not yet started from the end of the other's, never a running one. The
# gap workflow (about 80 s) started last would set the run's end with the other worker idle; started first, the
# short tests fill the other worker meanwhile.
LONGEST = "tests/workflow/test_gap_workflow.py::"


def pytest_collection_modifyitems(config, items):
    items.sort(key=lambda item: not item.nodeid.startswith(LONGEST))  # a stable sort: the rest keep their order


def pytest_collection_finish(session):
    """Start the real-SLURM check in the background where the run holds its test (tests/slurm_background.py)."""
    import slurm_background

    if session.config.option.collectonly or not any(i.nodeid.startswith(slurm_background.TEST) for i in session.items):
        return
    slurm_background.start(run_folder(session.config._tmp_path_factory, "slurm-check"))


def pytest_sessionfinish(session, exitstatus):
    import slurm_background

    slurm_background.finish(interrupted=exitstatus == pytest.ExitCode.INTERRUPTED)


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return ROOT


@pytest.fixture(scope="session")
def default_config() -> dict:
    with open(ROOT / "config.yaml") as fh:
        return yaml.safe_load(fh)


@pytest.fixture(scope="session")
def scene(default_config) -> SceneConfig:
    return SceneConfig.from_dict(default_config["scene"])


TINY_GRID = TableGrid(
    speed_min=0.15,
    speed_max=1.05,
    n_speeds=7,
    mass_min=0.2,
    mass_max=2.0,
    n_masses=6,
    friction_min=0.1,
    friction_max=0.6,
    n_frictions=6,
)


# the tests' tiny workflow configs build the table on TINY_GRID with this quick check (tests/config/core_small.yaml)
TINY_TABLE_CONFIG = ROOT / "tests" / "config" / "core_small.yaml"


def tiny_workflow_config(override: Path = TINY_TABLE_CONFIG) -> dict:
    """config.yaml with a tiny config over it (by default tests/config/core_small.yaml: the table settings of the
    tests' tiny workflow runs)."""
    from snakemake.utils import update_config

    cfg = yaml.safe_load((ROOT / "config.yaml").read_text())
    update_config(cfg, yaml.safe_load(override.read_text()))
    return cfg


def build_tiny_table(path: Path, *, threads: int = 2) -> None:
    """Write the tests' tiny table to ``path``: a 7 x 6 x 6 table of the real scene, built by ``imply table build`` as
    the workflow's table rule runs it on the tests' tiny configs, its 4-cell check included."""
    from imply.cli import main

    cfg = tiny_workflow_config()
    options = ["--scene-json", json.dumps(cfg["scene"]), "--grid-json", json.dumps(cfg["table"])]
    options += ["--check-json", json.dumps(cfg["table_check"]), "--threads", str(threads)]
    assert main(["table", "build", *options, "-o", str(path)]) == 0


@pytest.fixture(scope="session")
def tiny_table_path(tmp_path_factory) -> Path:
    """The tests' tiny table (:func:`build_tiny_table`), built once for all of the run's test workers: the workflow
    tests plant it instead of building it again."""
    return built_once(tmp_path_factory, "tiny-table", lambda folder: build_tiny_table(folder / "tiny.npz")) / "tiny.npz"


@pytest.fixture(scope="session")
def tiny_table(tiny_table_path) -> PushTable:
    """The tiny table (``tiny_table_path``) loaded: enough to exercise code paths in a second."""
    return PushTable.load(tiny_table_path)


@pytest.fixture(scope="session")
def analytic_table() -> PushTable:
    """A closed-form table, log d = 2 log v - log mu - 0.5 log m v: fast and exactly known."""
    speeds = np.linspace(0.15, 1.05, 19)
    masses = np.geomspace(0.2, 2.0, 25)
    frictions = np.geomspace(0.1, 0.6, 21)
    v, m, mu = np.meshgrid(speeds, masses, frictions, indexing="ij")
    return PushTable(speeds, masses, frictions, analytic_log_d(v, m, mu))


def analytic_log_d(v, m, mu):
    return 2 * np.log(v) - np.log(mu) - 0.5 * np.log(m) * v - 3.0


@pytest.fixture(scope="session")
def full_table() -> PushTable:
    """The default 19 x 25 x 21 table, read from tests/stored/default_table.npz (building it takes four
    CPU-minutes); tests/test_table.py holds the file to the builder, cell by cell on a sample."""
    from imply.table import config_digest
    from stored.make_default_table import STORED_TABLE, default_scene_and_grid

    scene, grid = default_scene_and_grid()
    key = config_digest({"scene": scene.to_dict(), "grid": grid.__dict__})
    table = PushTable.load(STORED_TABLE)
    if table.meta.get("config_digest") != key:
        pytest.fail(
            f"{STORED_TABLE.relative_to(ROOT)} was built for another scene or table grid than config.yaml's "
            f"(config digest {table.meta.get('config_digest')} against {key}): python tests/stored/make_default_table.py"
        )
    return table


@pytest.fixture(scope="session")
def docs_site(tmp_path_factory) -> Path:
    """The documentation site, built strict (warnings as errors) by one test worker for every test that reads it."""
    import subprocess
    import sys

    def build(out: Path) -> None:
        env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
        command = [sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "--site-dir", str(out / "site")]
        proc = subprocess.run(command, cwd=ROOT, capture_output=True, text=True, env=env)
        assert proc.returncode == 0, proc.stderr[-3000:]

    return built_once(tmp_path_factory, "docs-site", build) / "site"


@pytest.fixture(scope="session")
def imply_server(tmp_path_factory):
    """A fork server for ``snakemake`` runs and ``imply`` jobs (tests/forkserver.py), one per test worker: the
    environment that sends a workflow's commands to it (its clients first on PATH, the socket in IMPLY_FORKSERVER)."""
    import subprocess
    import sys
    import time

    from forkserver import write_clients

    folder = tmp_path_factory.mktemp("forkserver")
    sock, log = folder / "imply.sock", folder / "server.log"
    with open(log, "w") as out:
        server = subprocess.Popen([sys.executable, str(ROOT / "tests" / "forkserver.py"), str(sock)], stderr=out)
    deadline = time.monotonic() + 120
    while not sock.exists():
        if server.poll() is not None or time.monotonic() > deadline:
            server.kill()
            pytest.fail(f"the imply fork server did not start:\n{log.read_text()[-3000:]}")
        time.sleep(0.1)
    clients = write_clients(folder / "bin")
    yield {"PATH": f"{clients}{os.pathsep}{os.environ['PATH']}", "IMPLY_FORKSERVER": str(sock)}
    server.terminate()
    server.wait(timeout=30)


def send_to_imply_server(env: pytest.MonkeyPatch, server: dict[str, str]) -> None:
    """Set, through ``env``, the environment that sends commands to the fork server (``imply_server``'s value)."""
    for name, value in server.items():
        env.setenv(name, value)


@pytest.fixture
def forked_imply(imply_server, monkeypatch):
    """Run this test's ``snakemake`` (through :func:`workflow_helpers.snakemake_command`) and its workflow's ``imply``
    jobs in forks of the worker's fork server (``imply_server``)."""
    send_to_imply_server(monkeypatch, imply_server)


@pytest.fixture
def one_torch_thread():
    """Run a test on one torch thread (tiny tensors: more threads only contend with the rest of the suite)."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


# -- evaluation suites (tests/evaluate) ------------------------------------------------


@pytest.fixture(scope="session")
def tiny_suite(tiny_table_path, tmp_path_factory) -> Path:
    """The folder of a tiny suite: N = 6 objects, K = 5 speeds, C = 1, T = 4 frames of 16 x 64 px, M = 12, M_c = 9."""
    from suite_helpers import build_tiny_suite

    # built by one test worker for all of them
    return (
        built_once(tmp_path_factory, "tiny-suite", lambda folder: build_tiny_suite(folder / "tiny", tiny_table_path))
        / "tiny"
    )


@pytest.fixture(scope="session")
def known_answers_suite(full_table, tmp_path_factory) -> Path:
    """A suite at the study's camera and table, big enough for the stand-ins' known answers: N = 30 objects,
    readouts fitted on 40 training objects' clips and checked on 20 others'."""
    from imply.data.clips import ClipsConfig
    from imply.evaluate.suite import SuiteConfig, build_suite
    from imply.score import ScoreConfig
    from imply.sim import SceneConfig

    def build(folder: Path) -> None:
        full_table.save(folder / "table.npz")
        build_suite(
            SuiteConfig(n_objects=30, n_readout_train=40, n_readout_check=20),
            clips=ClipsConfig(),
            scene=SceneConfig(),
            speeds=ScoreConfig(),
            table_path=folder / "table.npz",
            out_dir=folder / "known_answers",
            nthread=2,
            progress=False,
        )

    # built by one test worker for all of them
    return built_once(tmp_path_factory, "known-answers-suite", build) / "known_answers"


@pytest.fixture(scope="session")
def effect_cache(tmp_path_factory) -> Path:
    """One effect-table cache for the diagnostic's tests (tables are keyed by the grid and effects they hold), shared
    by the run's test workers and started from tests/stored/effect-cache (the tables the tests ask for, built once by
    tests/stored/make_effect_cache.py): a table missing there is built and written whole (``imply.io``), so a worker
    finds it built or builds it."""
    from stored.make_effect_cache import STORED_EFFECT_CACHE

    folder = run_folder(tmp_path_factory, "effect-cache")
    for stored in STORED_EFFECT_CACHE.iterdir():
        if not (folder / stored.name).exists():
            copy_whole(stored, folder / stored.name)
    return folder
