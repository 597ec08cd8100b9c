"""Floating point that does not depend on the machine: the numerical kernels every job of the study uses.

PyTorch, MKL, oneDNN, NumPy and OpenBLAS each pick their kernels at run time from the
processor's instruction set (AVX2 on many laptops, AVX-512 on most servers). The kernels
sum in different orders, so one training run gives different weights on two machines,
and Section 5's numbers move with them. Pinning every library to its AVX2 code path
(which every x86-64 processor of the last ten years runs) makes a job give the same bytes
on any such machine, for the same thread counts (which the config fixes per rule).

The workflow puts :func:`environment` into the environment of every job
(``workflow/rules/common.smk``), so the pin travels with the study rather than with the
person who runs it; config ``kernels.pin: native`` turns it off. The variables must be
set before the libraries load, which is why they are the jobs' environment and not a
call inside the package.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from imply.options import Config, option

PINS = ("avx2", "native")

# NumPy's dispatch targets above AVX2 (numpy 2's names; unknown names are ignored)
_NUMPY_ABOVE_AVX2 = "X86_V4 AVX512F AVX512CD AVX512_SKX AVX512_CLX AVX512_CNL AVX512_ICL AVX512_SPR"


@dataclass(frozen=True, kw_only=True)
class KernelsConfig(Config):
    """The numerical kernels of the study's jobs (config ``kernels``)."""

    config_key: ClassVar[str] = "kernels"

    pin: str = option(
        "avx2",
        doc="instruction set every library computes with (avx2: the same bytes on any x86-64 machine with AVX2; "
        "native: each library's own choice, faster on some machines, not reproducible across them)",
        choices=PINS,
    )

    def __post_init__(self) -> None:
        if self.pin not in PINS:
            raise ValueError(f"kernels.pin: {self.pin!r} is not one of {', '.join(PINS)}")


def environment(pin: str) -> dict[str, str]:
    """The environment variables that pin every numerical library to ``pin``'s code path ({} for native)."""
    if pin == "native":
        return {}
    if pin != "avx2":
        raise ValueError(f"unknown kernel pin {pin!r} (known: {', '.join(PINS)})")
    return {
        "ATEN_CPU_CAPABILITY": "avx2",  # PyTorch's own vectorised kernels
        "MKL_CBWR": "AVX2,STRICT",  # MKL's conditional numerical reproducibility (PyTorch's BLAS)
        "MKL_ENABLE_INSTRUCTIONS": "AVX2",
        "ONEDNN_MAX_CPU_ISA": "AVX2",  # PyTorch's convolutions and some matrix products
        "NPY_DISABLE_CPU_FEATURES": _NUMPY_ABOVE_AVX2,  # NumPy's dispatched loops
        "OPENBLAS_CORETYPE": "Haswell",  # NumPy's and SciPy's BLAS
    }
