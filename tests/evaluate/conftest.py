"""A tiny evaluation suite, built once per test session for every test of imply.evaluate."""

from __future__ import annotations

from pathlib import Path

import pytest

from suite_helpers import build_tiny_suite


@pytest.fixture(scope="session")
def tiny_suite(tiny_table_path, tmp_path_factory) -> Path:
    """The folder of a tiny suite: N = 6 objects, K = 5 speeds, C = 1, T = 4 frames of 16 x 64 px, M = 12, M_c = 9."""
    return build_tiny_suite(tmp_path_factory.mktemp("suites") / "tiny", tiny_table_path)


@pytest.fixture(scope="session")
def known_answers_suite(full_table, tmp_path_factory) -> Path:
    """A suite at the study's camera and table, big enough for the stand-ins' known answers: N = 30 objects,
    readouts fitted on 40 training objects' clips and checked on 20 others'."""
    from imply.data.clips import ClipsConfig
    from imply.evaluate.suite import SuiteConfig, build_suite
    from imply.score import ScoreConfig
    from imply.sim import SceneConfig

    folder = tmp_path_factory.mktemp("suites")
    full_table.save(folder / "table.npz")
    return build_suite(
        SuiteConfig(n_objects=30, n_readout_train=40, n_readout_check=20),
        clips=ClipsConfig(),
        scene=SceneConfig(),
        speeds=ScoreConfig(),
        table_path=folder / "table.npz",
        out_dir=folder / "known_answers",
        nthread=2,
        progress=False,
    )
