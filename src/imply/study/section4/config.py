"""Settings of the controlled validation: config section ``section4``, one class per sub-section.

Each workflow rule passes only the sub-sections its step reads (``--objects-json``,
``--standins-json``, ...), so editing e.g. ``section4.selection`` reruns only the
selection and what follows it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from imply.options import Config, Range, option


@dataclass(frozen=True, kw_only=True)
class ObjectsConfig(Config):
    """``section4.objects``: how many objects, and the ranges their physics is drawn from.

    Mass and friction are log-uniform within ``mass``/``friction`` (inside the table's
    range); each box half-extent is the scene's canonical one times exp(size_log_sd z).
    """

    config_key: ClassVar[str] = "section4.objects"

    n: int = option(200, doc="evaluation objects (paper: 200)", minimum=2, required=True)
    n_train: int = option(200, doc="training objects that define the typical displacement", minimum=2, required=True)
    mass: Range = option(Range(min=0.2, max=2.0), doc="kg, log-uniform, inside the table's range", required=True)
    friction: Range = option(Range(min=0.1, max=0.6), doc="log-uniform, inside the table's range", required=True)
    size_log_sd: float = option(
        0.05, doc="each box half-extent = canonical * exp(sd * z)", minimum=0, maximum=0.5, required=True
    )

    def __post_init__(self) -> None:
        if self.n < 2 or self.n_train < 2:
            raise ValueError("need at least 2 evaluation and 2 training objects")
        if self.size_log_sd < 0:
            raise ValueError(f"size_log_sd must be >= 0, not {self.size_log_sd:g}")


@dataclass(frozen=True, kw_only=True)
class StandinsConfig(Config):
    """``section4.standins``: the jitter model's spread and how many rollout sets it draws."""

    config_key: ClassVar[str] = "section4.standins"

    jitter_sd: float = option(
        0.25, doc="log-normal sd of each jitter rollout's (m, mu) around the truth", minimum=0, required=True
    )
    jitter_draws: int = option(3, doc="jitter rollout sets per object", minimum=1, required=True)

    def __post_init__(self) -> None:
        if self.jitter_sd < 0 or self.jitter_draws < 1:
            raise ValueError("jitter_sd must be >= 0 and jitter_draws >= 1")


@dataclass(frozen=True, kw_only=True)
class NoiseConfig(Config):
    """``section4.noise``: the readout-noise levels of Table 2 (log sd, multiplicative)."""

    config_key: ClassVar[str] = "section4.noise"

    sds: tuple[float, ...] = option(
        (0.0, 0.03, 0.06, 0.1, 0.2),
        doc="multiplicative log-normal readout noise (log sd)",
        min_items=1,
        max_items=26,
        items={"minimum": 0},
        required=True,
    )

    def __post_init__(self) -> None:
        if not self.sds or any(s < 0 for s in self.sds):
            raise ValueError("sds must be a non-empty list of levels >= 0")


@dataclass(frozen=True, kw_only=True)
class SelectionConfig(Config):
    """``section4.selection``: candidates per object, their readout noise, where the miss is measured."""

    config_key: ClassVar[str] = "section4.selection"

    k: int = option(
        4, doc="candidates per object: the oracle's and k-1 from the other stand-ins", minimum=2, required=True
    )
    noise_sd: float = option(0.03, doc="readout noise on every candidate (log sd)", minimum=0, required=True)
    query_speed: float = option(
        0.55,
        doc="the miss is measured at this query speed (one of score.query_speeds)",
        exclusive_minimum=0,
        required=True,
    )
    within_mm: float = option(10.0, doc='the "within N mm" share', exclusive_minimum=0, required=True)

    def __post_init__(self) -> None:
        if self.k < 2:
            raise ValueError(f"k must be at least 2, not {self.k}")
        if self.noise_sd < 0 or self.within_mm <= 0:
            raise ValueError("noise_sd must be >= 0 and within_mm > 0")


@dataclass(frozen=True, kw_only=True)
class Section4Config(Config):
    """Config section ``section4``: the controlled validation (paper Section 4)."""

    config_key: ClassVar[str] = "section4"

    seed: int = option(4, doc="seed of every draw of the stage", minimum=0, required=True)
    objects: ObjectsConfig = option(ObjectsConfig(), doc="the objects", required=True)
    standins: StandinsConfig = option(StandinsConfig(), doc="the stand-in models", required=True)
    noise: NoiseConfig = option(NoiseConfig(), doc="readout noise levels of Table 2", required=True)
    selection: SelectionConfig = option(SelectionConfig(), doc="the selection study", required=True)
