"""A tiny evaluation suite, built once per test session for every test of imply.evaluate."""

from __future__ import annotations

from pathlib import Path

import pytest

from suite_helpers import build_tiny_suite


@pytest.fixture(scope="session")
def tiny_suite(tiny_table_path, tmp_path_factory) -> Path:
    """The folder of a tiny suite: N = 6 objects, K = 5 speeds, C = 1, T = 4 frames of 16 x 64 px, M = 12, M_c = 9."""
    return build_tiny_suite(tmp_path_factory.mktemp("suites") / "tiny", tiny_table_path)
