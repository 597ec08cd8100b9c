"""The study's numerical kernels (imply.kernels): pinned to AVX2 in every job's environment by the workflow."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from imply.kernels import KernelsConfig, environment

ROOT = Path(__file__).resolve().parents[1]

PROBE = """
import json, numpy, torch
from numpy._core._multiarray_umath import __cpu_features__ as f
x = torch.linspace(0.1, 3.0, 4099)
print(json.dumps({"torch": torch.backends.cpu.get_cpu_capability(), "numpy_v4": bool(f.get("X86_V4")),
                  "sum": float((x.exp() * x.sin()).sum())}))
"""


def _probe(env: dict[str, str]) -> dict:
    clean = {k: v for k, v in os.environ.items() if k not in environment("avx2")}
    out = subprocess.run(
        [sys.executable, "-c", PROBE], env={**clean, **env}, capture_output=True, text=True, check=True
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_the_pin_reaches_torch_and_numpy():
    pinned = _probe(environment("avx2"))
    assert pinned["torch"] == "AVX2"
    assert pinned["numpy_v4"] is False


def test_the_default_pins_numpy_and_leaves_torch_its_own_kernels():
    assert KernelsConfig().pin == "numpy-avx2"
    env = environment("numpy-avx2")
    assert _probe(env)["numpy_v4"] is False
    assert not any(k.startswith(("ATEN", "MKL", "ONEDNN")) for k in env)
    assert set(env) < set(environment("avx2"))


def test_native_sets_nothing_and_unknown_pins_are_refused():
    assert environment("native") == {}
    with pytest.raises(ValueError, match="avx512"):
        environment("avx512")
    with pytest.raises(ValueError, match="kernels.pin"):
        KernelsConfig(pin="fast")


def test_the_workflow_puts_the_pin_into_every_job():
    common = (ROOT / "workflow" / "rules" / "common.smk").read_text()
    assert re.search(r"os\.environ\.update\(kernel_environment\(", common)
    rules = "\n".join(p.read_text() for p in (ROOT / "workflow" / "rules").glob("*.smk"))
    # jobs that ran inside Snakemake's own process would not see the pin
    assert not re.search(r"^\s+(run|script):", rules, re.M)
