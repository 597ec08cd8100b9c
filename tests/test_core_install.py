"""The core install runs what a user runs: every extra's modules made unimportable, the user's commands still work,
and a command that needs an extra says which in one line.

Each command runs as ``python -m imply.cli`` in a fresh process whose ``sitecustomize`` refuses every module of
:data:`imply.extras.EXTRA_OF_MODULE` (torch, snakemake, scikit-learn, PyBullet, SAPIEN, PyAV, ...), as an
environment with only ``pip install imply`` would. The same three user checks run against a wheel installed in a
fresh virtual environment in ``.ci/core-install``.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import pandas as pd
import pytest

from imply.extras import EXTRA_OF_MODULE, NOT_IN_CORE
from sample_inputs import EFFECT_GRID_JSON
from video_helpers import oracle_pngs

ROOT = Path(__file__).resolve().parents[1]

BLOCKER = """
import sys

BLOCKED = {blocked!r}


class _Blocked:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            raise ModuleNotFoundError(f"No module named {{name!r}}", name=name)
        return None


sys.meta_path.insert(0, _Blocked())
"""

FAST_DIAGNOSIS = [
    "--effects",
    "tilt,speed_gain,viscous",
    "--effect-grid-json",
    EFFECT_GRID_JSON,
    "--threads",
    "2",
]


@pytest.fixture(scope="module")
def core_env(tmp_path_factory) -> dict[str, str]:
    """An environment in which every extra's modules fail to import."""
    folder = tmp_path_factory.mktemp("core")
    (folder / "sitecustomize.py").write_text(BLOCKER.format(blocked={*EXTRA_OF_MODULE, *NOT_IN_CORE}))
    return {**os.environ, "PYTHONPATH": str(folder), "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}


def imply(*args: str, env: dict[str, str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "imply.cli", *args], env=env, cwd=cwd, capture_output=True, text=True, timeout=600
    )


def test_no_extra_s_module_imports_in_the_core_environment(core_env, tmp_path):
    for module in (*EXTRA_OF_MODULE, *NOT_IN_CORE):
        proc = subprocess.run([sys.executable, "-c", f"import {module}"], env=core_env, capture_output=True, text=True)
        assert proc.returncode == 1 and "ModuleNotFoundError" in proc.stderr, module


def test_diagnose_score_and_evaluate_check_run_on_the_core(
    core_env, tmp_path, tiny_table_path, tiny_suite, effect_cache
):
    table = str(tiny_table_path)
    # the diagnose tutorial's log: a tilted table, found and written into the scene
    scene = '{"option": {"gravity": "0.25 0 -9.81"}}'
    sim = imply("sim", "pushes", str(ROOT / "examples/pushes.csv"), "--scene-json", scene, "-o", "pushlog.csv",
                env=core_env, cwd=tmp_path)  # fmt: skip
    assert sim.returncode == 0, sim.stderr[-2000:]
    diagnosis = imply("diagnose", "pushlog.csv", "--table", table, "--noise-sd", "0.02", *FAST_DIAGNOSIS,
                      "--cache-dir", str(effect_cache), "-o", "gap-report", env=core_env, cwd=tmp_path)  # fmt: skip
    assert diagnosis.returncode == 0, diagnosis.stderr[-2000:]
    summary = json.loads((tmp_path / "gap-report" / "summary.json").read_text())
    assert summary["verdict"]["effects"] == ["tilt"]
    assert summary["simulator"]["share_closed"] > 0.8  # re-simulated through mujoco.sysid without its report packages
    assert (tmp_path / "gap-report" / "corrected.xml").is_file() and (tmp_path / "gap-report" / "ranking.png").is_file()
    # the example rollouts file
    score = imply("score", str(ROOT / "examples/rollouts.csv"), "--table", table, "-o", "scores.csv",
                  env=core_env, cwd=tmp_path)  # fmt: skip
    assert score.returncode == 0, score.stderr[-2000:]
    assert list(pd.read_csv(tmp_path / "scores.csv").object_id) == ["a", "b"]
    # an exported suite's videos checked before scoring: PNG frames need only the core
    videos = oracle_pngs(tiny_suite, tmp_path / "videos")
    check = imply(
        "evaluate", "--videos", str(videos), "--suite", str(tiny_suite), "--check", env=core_env, cwd=tmp_path
    )
    assert check.returncode == 0, check.stderr[-2000:]
    assert "missing" not in check.stderr.lower()


@pytest.mark.parametrize(
    ("argv", "extra"),
    [
        (["study", "encoder", "pretrain", "--clips", "c.npz", "--encoder-json", "{}", "-o", "e.pt"], "study"),
        (["suite", "export", "SUITE", "-o", "pkg"], "video"),
        (["score", "rollouts.parquet", "--table", "TABLE", "-o", "scores.csv"], "parquet"),
    ],
)
def test_a_command_that_needs_a_missing_extra_names_it_in_one_line(
    core_env, tmp_path, tiny_suite, tiny_table_path, argv, extra
):
    (tmp_path / "c.npz").write_bytes(b"")
    pd.read_csv(ROOT / "examples/rollouts.csv").to_parquet(tmp_path / "rollouts.parquet")
    argv = [{"SUITE": str(tiny_suite), "TABLE": str(tiny_table_path)}.get(a, a) for a in argv]
    proc = imply(*argv, env=core_env, cwd=tmp_path)
    lines = [line for line in proc.stderr.strip().splitlines() if not re.match(r"\d{4}-\d\d-\d\d ", line)]
    assert proc.returncode == 2
    assert len(lines) == 1 and f"the '{extra}' extra installs: pip install 'imply[{extra}]'" in lines[0], proc.stderr
    assert not {"e.pt", "pkg", "scores.csv"} & {p.name for p in tmp_path.iterdir()}


def test_every_extra_module_belongs_to_its_extra_in_pyproject():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    extras = project["optional-dependencies"]

    def names(requirements: list[str]) -> set[str]:
        return {re.split(r"[<>=\[ ;]", r, maxsplit=1)[0] for r in requirements}

    core = names(project["dependencies"])
    for module, (extra, distribution) in EXTRA_OF_MODULE.items():
        assert distribution in names(extras[extra]), (module, extra)
        assert distribution not in core, module
    assert "imply" in names(extras["test"]) and "imply[study]" in extras["test"]  # the tests run the study
