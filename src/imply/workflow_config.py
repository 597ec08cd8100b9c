"""The whole study configuration (``config.yaml``) as one settings class, and the schema the workflow checks it with.

:class:`StudyConfig` names every section's settings class; its defaults are the study's
values, so ``StudyConfig().to_dict()`` is ``config.yaml``'s content (tests hold the two
to each other). :func:`write_schema` turns it into ``workflow/schemas/config.schema.yaml``
(:func:`imply.options.json_schema`): the workflow reads that file when Snakemake reads
the Snakefile, so the check needs none of the modules imported here. Regenerate it after
changing a settings class::

    python -m imply.workflow_config workflow/schemas/config.schema.yaml
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import yaml

from imply.config_check import PAPER_STAGES
from imply.data.clips import ClipsConfig
from imply.diagnose.analysis import DiagnosisConfig
from imply.diagnose.physics.effect_tables import CoarseGrid
from imply.evaluate.config import EvaluateConfig
from imply.evaluate.suite import SuiteConfig
from imply.kernels import KernelsConfig
from imply.models.config import ModelConfig
from imply.models.encoder import EncoderConfig
from imply.options import Config, json_schema, option
from imply.readout import ReadoutConfig
from imply.realworld.cases import BenchmarkConfig, ContactBenchmarkConfig
from imply.realworld.lab import LabBenchmarkConfig
from imply.score import ScoreConfig
from imply.sim.scene import SceneConfig
from imply.study.pixel_model import PixelConfig
from imply.study.section4.config import Section4Config
from imply.table import TableCheckConfig, TableConfig

SCHEMA_HEADER = (
    "# Written by `python -m imply.workflow_config workflow/schemas/config.schema.yaml` from imply.workflow_config.StudyConfig\n"
    "# (the settings classes are the one source of every option); do not edit by hand.\n"
)


@dataclass(frozen=True, kw_only=True)
class GapConfig(Config):
    """Config section ``gap``: the sim-to-real diagnostic and its benchmark."""

    config_key: ClassVar[str] = "gap"

    candidates: tuple[str, ...] | None = option(
        None, doc="candidate effects (imply.diagnose.physics.candidates.CANDIDATES names); null: the whole library"
    )
    effect_grid: CoarseGrid = option(CoarseGrid(), doc="the effect tables' grids", required=True)
    diagnose: DiagnosisConfig = option(DiagnosisConfig(), doc="the diagnostic's settings", required=True)
    benchmark: BenchmarkConfig = option(BenchmarkConfig(), doc="the benchmark's logs and targets", required=True)
    contact_benchmark: ContactBenchmarkConfig = option(
        ContactBenchmarkConfig(), doc="the contact benchmark: other contact models and another engine", required=True
    )
    lab_benchmark: LabBenchmarkConfig = option(
        LabBenchmarkConfig(),
        doc="the lab benchmark: pushes with calibration probes, development and sealed sets by "
        "engine (imply.realworld.lab)",
        required=True,
    )


@dataclass(frozen=True, kw_only=True)
class PaperConfig(Config):
    """Config section ``paper`` (optional): which stages the paper merge takes."""

    config_key: ClassVar[str] = "paper"

    stages: tuple[str, ...] = option(
        PAPER_STAGES,
        doc="merge only these stages' result parts (imply.config_check.PAPER_STAGES)",
        items={"pattern": "^[A-Za-z0-9_]+$"},
    )


@dataclass(frozen=True, kw_only=True)
class StudyConfig(Config):
    """IMPLY workflow configuration (config.yaml): every section of the study."""

    config_key: ClassVar[str] = "config"

    threads: int = option(2, doc="threads of the multi-threaded rules", minimum=1, required=True)
    kernels: KernelsConfig = option(KernelsConfig(), doc="the numerical kernels every job computes with")
    scene: SceneConfig = option(SceneConfig(), doc="the push scene", required=True)
    table: TableConfig = option(TableConfig(), doc="the push table's grid", required=True)
    table_check: TableCheckConfig = option(TableCheckConfig(), doc="the table's numerical error check")
    score: ScoreConfig = option(ScoreConfig(), doc="scoring", required=True)
    section4: Section4Config = option(Section4Config(), doc="the controlled validation", required=True)
    gap: GapConfig = option(GapConfig(), doc="the sim-to-real diagnostic", required=True)
    clips: ClipsConfig = option(ClipsConfig(), doc="rendered push clips", required=True)
    encoder: EncoderConfig = option(EncoderConfig(), doc="the frozen encoder", required=True)
    readout: ReadoutConfig = option(ReadoutConfig(), doc="displacement readouts", required=True)
    model: ModelConfig = option(ModelConfig(), doc="the predictor and Section 5 scoring", required=True)
    suite: SuiteConfig = option(SuiteConfig(), doc="the frozen evaluation suite of imply evaluate", required=True)
    evaluate: EvaluateConfig = option(EvaluateConfig(), doc="how imply evaluate asks and scores", required=True)
    pixel: PixelConfig = option(PixelConfig(), doc="the pixel-space world model beyond the paper", required=True)
    paper: PaperConfig = option(PaperConfig(), doc="the paper merge")


def study_schema() -> dict[str, Any]:
    """The JSON schema of the whole config (what ``workflow/schemas/config.schema.yaml`` holds)."""
    return json_schema(StudyConfig, title="IMPLY workflow configuration (config.yaml)")


def schema_text() -> str:
    """:func:`study_schema` as the YAML text of the schema file."""
    return SCHEMA_HEADER + yaml.safe_dump(study_schema(), sort_keys=False, width=120, allow_unicode=True)


def write_schema(path: str | Path) -> None:
    """Write :func:`schema_text` to ``path``."""
    Path(path).write_text(schema_text())


if __name__ == "__main__":
    write_schema(sys.argv[1] if len(sys.argv) > 1 else "workflow/schemas/config.schema.yaml")
