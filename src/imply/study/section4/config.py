"""Settings of the controlled validation: config section ``section4``, one class per sub-section.

Each workflow rule passes only the sub-sections its step reads (``--objects-json``,
``--standins-json``, ...), so editing e.g. ``section4.selection`` reruns only the
selection and what follows it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from imply.options import Config, Range


@dataclass(frozen=True, kw_only=True)
class ObjectsConfig(Config):
    """``section4.objects``: how many objects, and the ranges their physics is drawn from.

    Mass and friction are log-uniform within ``mass``/``friction`` (inside the table's
    range); each box half-extent is the scene's canonical one times exp(size_log_sd z).
    """

    config_key: ClassVar[str] = "section4.objects"

    n: int = 200
    n_train: int = 200
    mass: Range = Range(min=0.2, max=2.0)
    friction: Range = Range(min=0.1, max=0.6)
    size_log_sd: float = 0.05

    def __post_init__(self) -> None:
        if self.n < 2 or self.n_train < 2:
            raise ValueError("need at least 2 evaluation and 2 training objects")
        if self.size_log_sd < 0:
            raise ValueError(f"size_log_sd must be >= 0, not {self.size_log_sd:g}")


@dataclass(frozen=True, kw_only=True)
class StandinsConfig(Config):
    """``section4.standins``: the jitter model's spread and how many rollout sets it draws."""

    config_key: ClassVar[str] = "section4.standins"

    jitter_sd: float = 0.25
    jitter_draws: int = 3

    def __post_init__(self) -> None:
        if self.jitter_sd < 0 or self.jitter_draws < 1:
            raise ValueError("jitter_sd must be >= 0 and jitter_draws >= 1")


@dataclass(frozen=True, kw_only=True)
class NoiseConfig(Config):
    """``section4.noise``: the readout-noise levels of Table 2 (log sd, multiplicative)."""

    config_key: ClassVar[str] = "section4.noise"

    sds: tuple[float, ...] = (0.0, 0.03, 0.06, 0.1, 0.2)

    def __post_init__(self) -> None:
        if not self.sds or any(s < 0 for s in self.sds):
            raise ValueError("sds must be a non-empty list of levels >= 0")


@dataclass(frozen=True, kw_only=True)
class SelectionConfig(Config):
    """``section4.selection``: candidates per object, their readout noise, where the miss is measured."""

    config_key: ClassVar[str] = "section4.selection"

    k: int = 4
    noise_sd: float = 0.03
    query_speed: float = 0.55
    within_mm: float = 10.0

    def __post_init__(self) -> None:
        if self.k < 2:
            raise ValueError(f"k must be at least 2, not {self.k}")
        if self.noise_sd < 0 or self.within_mm <= 0:
            raise ValueError("noise_sd must be >= 0 and within_mm > 0")
