"""Settings of ``imply evaluate`` (config section ``evaluate``), importable without the heavy modules."""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

from imply.options import Config, option

CONDITIONS: tuple[str, ...] = ("own", "other", "none")


def parse_conditions(text: str) -> tuple[str, ...]:
    """``"own, other"`` -> ``("own", "other")``; ValueError naming the unknown ones (or none given)."""
    conditions = tuple(c.strip() for c in text.split(",") if c.strip())
    bad = [c for c in conditions if c not in CONDITIONS]
    if bad or not conditions:
        raise ValueError(f"{', '.join(bad) or 'none given'} (known: {', '.join(CONDITIONS)})")
    return conditions


@dataclass(frozen=True, kw_only=True)
class EvaluateConfig(Config):
    """Config section ``evaluate``: what ``imply evaluate`` asks and how it scores (the study's runs use it too)."""

    config_key: ClassVar[str] = "evaluate"

    conditions: tuple[str, ...] = option(
        CONDITIONS, doc="calibration conditions asked: own, other (the partner's), none", min_items=1, unique=True
    )
    samples: int = option(16, doc="sample sets per object asked of a stochastic model", minimum=1)
    bootstrap: int = option(1000, doc="bootstrap resamples of the objects for the 95% intervals", minimum=0)
    seed: int = option(0, doc="seed of the bootstrap and of the random selection rule", minimum=0)
    static_limit: float = option(
        0.003, doc="a set whose every slide is below this (m) is flagged static", exclusive_minimum=0
    )

    def __post_init__(self) -> None:
        bad = [c for c in self.conditions if c not in CONDITIONS]
        if bad or not self.conditions:
            raise ValueError(f"conditions must be among {', '.join(CONDITIONS)}, not {', '.join(bad) or 'none'}")
