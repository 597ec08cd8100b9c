"""``imply study``: the study's workflow steps, one group per stage, which the workflow's rules call.

None of them is needed to score rollouts, evaluate a model or diagnose a robot's pushes; they are kept apart so
``imply --help`` lists what a user runs. Most need the ``study`` extra (``pip install 'imply[study]'``).
"""

from __future__ import annotations

import argparse
import importlib

STUDY_GROUPS: list[str] = ["section4", "clips", "encoder", "readout", "model", "section5", "gap", "pixel", "paper"]


def register(sub: argparse._SubParsersAction) -> None:
    study = sub.add_parser(
        "study",
        help="the study's workflow steps, run by 'snakemake --cores 2' (not needed to score, evaluate or diagnose)",
    )
    groups = study.add_subparsers(dest="study_command", required=True)
    for name in STUDY_GROUPS:
        importlib.import_module(f"imply.cli.{name}").register(groups)
