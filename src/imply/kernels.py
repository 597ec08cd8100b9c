"""The numerical kernels of every job of the study: which libraries are pinned to AVX2 (config ``kernels.pin``).

PyTorch, MKL, oneDNN, NumPy and OpenBLAS each pick their kernels at run time from the
processor's instruction set (AVX2 on many laptops, AVX-512 on most servers). The kernels
sum in different orders, so a job's floating point can differ between two machines.

What the study promises, and what the pin buys of it:

* **The same bytes on the same machine and config**, always (seeds come from config,
  thread counts are fixed per rule).
* **The same verdicts on every machine.** The Section 5 recipe is chosen so that neither the
  data-order seed nor the rounding decides a verdict (``benchmarks/s5_robustness.py``
  trains it under two kernel paths); how far its numbers move across roundings is in the
  recipe notes.
* **The default, ``numpy-avx2``**, pins NumPy, SciPy and OpenBLAS to their AVX2 paths: it
  costs nothing measurable and keeps Section 4 and the gap stage's numbers the same bytes on
  AMD and Intel machines. PyTorch computes on the machine's own kernels: pinning it too
  (``avx2``) cost 1.3 to 1.75 times a training step on an AVX-512 machine and did not give
  the same encoder features across CPU vendors, so it bought no verdict. ``native`` pins
  nothing.

The workflow puts :func:`environment` into the environment of every job
(``workflow/rules/common.smk``), so the pin travels with the study rather than with the
person who runs it. The variables must be set before the libraries load, which is why
they are the jobs' environment and not a call inside the package.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from imply.options import Config, option

PINS = ("avx2", "numpy-avx2", "native")

# NumPy's dispatch targets above AVX2 (numpy 2's names; unknown names are ignored)
_NUMPY_ABOVE_AVX2 = "X86_V4 AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR"


@dataclass(frozen=True, kw_only=True)
class KernelsConfig(Config):
    """The numerical kernels of the study's jobs (config ``kernels``)."""

    config_key: ClassVar[str] = "kernels"

    pin: str = option(
        "numpy-avx2",
        doc="instruction set the libraries compute with (avx2: every library on AVX2; numpy-avx2: NumPy, SciPy and "
        "OpenBLAS on AVX2, PyTorch on its own choice, which is up to 1.75 times faster on AVX-512 machines; native: "
        "each library's own choice)",
        choices=PINS,
    )

    def __post_init__(self) -> None:
        if self.pin not in PINS:
            raise ValueError(f"kernels.pin: {self.pin!r} is not one of {', '.join(PINS)}")


def environment(pin: str) -> dict[str, str]:
    """The environment variables that pin every numerical library to ``pin``'s code path ({} for native)."""
    if pin not in PINS:
        raise ValueError(f"unknown kernel pin {pin!r} (known: {', '.join(PINS)})")
    numpy = {
        "NPY_DISABLE_CPU_FEATURES": _NUMPY_ABOVE_AVX2,  # NumPy's dispatched loops
        "OPENBLAS_CORETYPE": "Haswell",  # NumPy's and SciPy's BLAS
    }
    torch = {
        "ATEN_CPU_CAPABILITY": "avx2",  # PyTorch's own vectorised kernels
        "MKL_CBWR": "AVX2,STRICT",  # MKL's conditional numerical reproducibility (PyTorch's BLAS)
        "MKL_ENABLE_INSTRUCTIONS": "AVX2",
        "ONEDNN_MAX_CPU_ISA": "AVX2",  # PyTorch's convolutions and some matrix products
    }
    return {"avx2": {**torch, **numpy}, "numpy-avx2": numpy, "native": {}}[pin]
