"""``imply study section5``: scores of the predictor's latent rollouts, the stage's result document and per-object table.

``--evaluation MODEL:SEED:FOLDER`` (repeatable) names each ``imply evaluate`` report: the
calibrated (``calib``) and context-free (``nocalib``) model of each data-order seed, its
rollouts read by the readout fitted on the suite's real clips; ``--suite MODEL:FOLDER``
the suite each model was scored on. The first seed, in increasing order, gives the
paper's Table 3 numbers; the second, its replication. Logic: :mod:`imply.study.section5`.
"""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from imply.cli.common import config_from_json, existing_file, int_range, json_arg, user_errors
from imply.models.config import ModelConfig
from imply.options import default_of

log = logging.getLogger("imply.section5")


def register(sub: argparse._SubParsersAction) -> None:
    s5 = sub.add_parser("section5", help="Section 5 scores of the predictor's rollouts (a result document)")
    s5.add_argument(
        "--evaluation",
        action="append",
        required=True,
        metavar="MODEL:SEED:FOLDER",
        help="an imply evaluate report of model calib|nocalib and data seed SEED (repeatable)",
    )
    s5.add_argument(
        "--suite",
        action="append",
        required=True,
        metavar="MODEL:FOLDER",
        help="the suite the model's reports were scored on (calib and nocalib)",
    )
    s5.add_argument("--table", type=existing_file, required=True, help="the push table (results/table/table.npz)")
    s5.add_argument(
        "--train-clips",
        type=existing_file,
        required=True,
        help="results/clips/train.csv: the training slides that define the object-blind baseline",
    )
    s5.add_argument("--score-json", type=json_arg, required=True, help="the config's score section (grid, floor)")
    s5.add_argument(
        "--selection-seed",
        type=int_range(0),
        default=default_of(ModelConfig, "selection_seed"),
        help="seed of the random selection rule",
    )
    s5.add_argument("--metrics", required=True, help="the result document (results/section5/metrics.json)")
    s5.add_argument("--per-object", required=True, help="per-object scores (results/section5/per_object.csv)")
    s5.set_defaults(func=cmd_section5)


def section5_part(result):
    """A Section 5 result's registered numbers and its claims checked on them, as the stage's paper part computes
    them (:class:`imply.study.section5.scoring.Section5Result` -> (name -> value, claims))."""
    import dataclasses

    from imply.paper.parts import build_part
    from imply.paper.results import producer_name
    from imply.study.section5.claims import section5_claims
    from imply.study.section5.scoring import section5_results

    document = {producer_name(section5_results): dataclasses.asdict(result)}
    return build_part("section5", document, claims=section5_claims)


def cmd_section5(args: argparse.Namespace) -> int:
    import pandas as pd

    from imply.evaluate.suite import SuiteError
    from imply.io import write_csv
    from imply.models.object_blind import typical_slide_of_clips
    from imply.paper.results import write_result
    from imply.score import ScoreConfig
    from imply.study.section5.rollouts import read_evaluations, suite_folders
    from imply.study.section5.scoring import section5_results
    from imply.table import PushTable

    with user_errors(ValueError, message="--suite {error}"):
        suites = suite_folders(args.suite)
    with user_errors(ValueError, SuiteError, OSError, KeyError, message="--evaluation: {error}"):
        tables, readouts = read_evaluations(args.evaluation, suites)
    seeds = sorted({s for _, s in tables})
    scorer = config_from_json(ScoreConfig, args.score_json, "--score-json").scorer(PushTable.load(args.table))
    with user_errors(ValueError, KeyError, message="--train-clips: {error}"):
        typical = typical_slide_of_clips(pd.read_csv(args.train_clips))
    result, per_object = section5_results(
        tables, scorer, seeds=seeds, selection_seed=args.selection_seed, typical=typical, readouts=readouts
    )
    write_result(args.metrics, section5_results, result)
    write_csv(args.per_object, per_object)
    log.info("section 5 scores of seeds %s -> %s", seeds, Path(args.metrics))
    return 0
