"""``imply study section4 STEP``: the controlled validation (paper Section 4), one workflow step per command.

Steps (``workflow/rules/section4.smk`` calls each with only the config it reads):
``objects`` -> ``truth`` -> ``standins`` -> ``scores`` -> ``metrics``, ``noise``,
``selection``; the stage's part, tables and figure are ``imply study paper`` commands. The
logic lives in :mod:`imply.study.section4`; a handler reads its inputs, calls one
function and writes its outputs. Config options: ``--seed`` (``section4.seed``),
``--objects-json``/``--standins-json``/``--noise-json``/``--selection-json`` (the
sub-sections of ``section4``), ``--score-json`` (``score``), ``--scene-json`` (``scene``).
"""

from __future__ import annotations

import argparse
import functools
import logging
from pathlib import Path
from typing import TYPE_CHECKING

from imply.cli.common import config_from_json, existing_file, int_range, json_arg, user_errors

if TYPE_CHECKING:
    import pandas as pd

log = logging.getLogger("imply.section4")


# what each step reads and writes (results/section4/ in the workflow)
STEP_FILES = {
    "table": "the push table (results/table/table.npz)",
    "objects": "the drawn objects (results/section4/objects.csv)",
    "truth": "the objects' true pushes (results/section4/truth.csv)",
    "rollouts": "the stand-ins' rollouts (results/section4/rollouts.csv)",
    "scores": "every stand-in's scores (results/section4/scores.csv)",
    "choices": "the selection's choices, one row per object and rule, to write (.csv)",
}
STEP_OUTPUTS = {
    "objects": "the objects to write (.csv)",
    "truth": "the true pushes to write (.csv)",
    "standins": "the rollouts to write (.csv)",
    "scores": "the scores to write (.csv)",
    "metrics": "the result document to write (.json)",
    "noise": "the result document to write (.json)",
    "selection": "the result document to write (.json)",
}


def register(sub: argparse._SubParsersAction) -> None:
    s4 = sub.add_parser("section4", help="the controlled validation (paper Section 4), step by step")
    ssub = s4.add_subparsers(dest="section4_command", required=True)

    def step(name: str, help_: str, func, inputs: list[str], outputs: list[str], options: list[str]) -> None:
        p = ssub.add_parser(name, help=help_)
        for flag in inputs:
            p.add_argument(f"--{flag}", required=True, type=existing_file, help=STEP_FILES[flag])
        for flag in outputs:
            if flag == "output":
                p.add_argument("-o", "--output", required=True, help=STEP_OUTPUTS[name])
            else:
                p.add_argument(f"--{flag}", required=True, help=STEP_FILES[flag])
        for opt in options:
            if opt == "threads":
                p.add_argument("--threads", type=int_range(0), default=0, help="simulation threads (0: all CPUs)")
            elif opt == "seed":
                p.add_argument("--seed", type=int_range(0), required=True, help="config section4.seed")
            else:
                p.add_argument(f"--{opt}-json", type=json_arg, required=True, help=f"config key {opt!r} as JSON")
        p.set_defaults(func=_user_errors(func))

    step(
        "objects",
        "draw evaluation and training objects",
        cmd_objects,
        ["table"],
        ["output"],
        ["seed", "objects", "scene"],
    )
    step(
        "truth", "simulate the objects' true pushes", cmd_truth, ["objects"], ["output"], ["score", "scene", "threads"]
    )
    step(
        "standins",
        "the four stand-ins' rollouts",
        cmd_standins,
        ["objects", "truth", "table"],
        ["output"],
        ["seed", "standins", "score", "scene", "threads"],
    )
    step(
        "scores",
        "score every stand-in's rollouts",
        cmd_scores,
        ["objects", "truth", "rollouts", "table"],
        ["output"],
        ["score"],
    )
    step(
        "metrics",
        "Table 1 and the oracle's recovery (a result document)",
        cmd_metrics,
        ["scores", "table"],
        ["output"],
        ["standins", "score"],
    )
    step(
        "noise",
        "readout-noise sweep, Table 2 top (a result document)",
        cmd_noise,
        ["truth", "rollouts", "table"],
        ["output"],
        ["seed", "noise", "score"],
    )
    step(
        "selection",
        "selection among candidates, Table 2 bottom (a result document)",
        cmd_selection,
        ["truth", "rollouts", "table"],
        ["output", "choices"],
        ["seed", "selection", "score"],
    )
    p = ssub.add_parser(
        "through-evaluate",
        help="the four stand-ins through imply evaluate: their report and known answers (a result document)",
    )
    p.add_argument("--suite", required=True, help="the suite folder (results/suite)")
    p.add_argument("--report", required=True, help="the evaluation report folder to write")
    p.add_argument("-o", "--output", required=True, help="the known answers (a result document)")
    p.add_argument("--evaluate-json", type=json_arg, required=True, help="config key 'evaluate' as JSON")
    p.add_argument("--score-json", type=json_arg, required=True, help="config key 'score' as JSON")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_user_errors(cmd_through_evaluate))


def _user_errors(func):
    """Report bad inputs or settings in one line (exit 2) instead of a traceback."""

    @functools.wraps(func)
    def wrapper(args: argparse.Namespace) -> int:
        import pandas as pd

        from imply.table import TableError

        with (
            user_errors(TableError, ValueError, pd.errors.ParserError),
            user_errors(KeyError, message="missing setting or column {error}"),
        ):
            return func(args)

    return wrapper


def _table(args: argparse.Namespace):
    from imply.table import PushTable

    return PushTable.load(args.table)


def _scene(args: argparse.Namespace):
    from imply.sim import SceneConfig

    return config_from_json(SceneConfig, args.scene_json, "--scene-json")


def _score(args: argparse.Namespace):
    from imply.score import ScoreConfig

    return config_from_json(ScoreConfig, args.score_json, "--score-json")


def _csv(path: Path) -> pd.DataFrame:
    import pandas as pd

    return pd.read_csv(path, keep_default_na=True)


def cmd_objects(args: argparse.Namespace) -> int:
    from imply.io import write_csv
    from imply.study.section4.config import ObjectsConfig
    from imply.study.section4.objects import draw_objects

    cfg = config_from_json(ObjectsConfig, args.objects_json, "--objects-json")
    frame = draw_objects(cfg, scene=_scene(args), seed=args.seed, table=_table(args))
    write_csv(args.output, frame)
    log.info("drew %d objects -> %s", len(frame), args.output)
    return 0


def cmd_truth(args: argparse.Namespace) -> int:
    from imply.io import write_csv
    from imply.study.section4.objects import simulate_truth

    score = _score(args)
    frame = simulate_truth(
        _csv(args.objects),
        query_speeds=score.query_speeds,
        calibration_speeds=score.calibration_speeds,
        scene=_scene(args),
        nthread=args.threads,
        progress=True,
    )
    n_bad = int((~frame["ok"].astype(bool)).sum())
    if n_bad:
        log.warning("%d true pushes failed the simulator's checks; kept as simulated", n_bad)
    write_csv(args.output, frame)
    log.info("simulated %d true pushes -> %s", len(frame), args.output)
    return 0


def cmd_standins(args: argparse.Namespace) -> int:
    from imply.io import write_csv
    from imply.study.section4.config import StandinsConfig
    from imply.study.section4.standins import standin_rollouts

    score = _score(args)
    frame = standin_rollouts(
        _csv(args.objects),
        _csv(args.truth),
        settings=config_from_json(StandinsConfig, args.standins_json, "--standins-json"),
        seed=args.seed,
        table=_table(args),
        query_speeds=score.query_speeds,
        calibration_speeds=score.calibration_speeds,
        floor=score.readout_floor,
        scene=_scene(args),
        nthread=args.threads,
        progress=True,
    )
    write_csv(args.output, frame)
    log.info("wrote %d stand-in rollouts -> %s", len(frame), args.output)
    return 0


def cmd_scores(args: argparse.Namespace) -> int:
    from imply.io import write_csv
    from imply.study.section4.scoring import score_rollouts

    frame = score_rollouts(_table(args), _csv(args.objects), _csv(args.truth), _csv(args.rollouts), score=_score(args))
    write_csv(args.output, frame)
    log.info("scored %d rollout sets -> %s", len(frame), args.output)
    return 0


def cmd_metrics(args: argparse.Namespace) -> int:
    from imply.paper.results import write_result
    from imply.study.section4.config import StandinsConfig
    from imply.study.section4.scoring import standin_metrics

    standins = config_from_json(StandinsConfig, args.standins_json, "--standins-json")
    result = standin_metrics(
        _csv(args.scores), _table(args), jitter_sd=standins.jitter_sd, k_speeds=len(_score(args).query_speeds)
    )
    write_result(args.output, standin_metrics, result)
    log.info("Table 1 metrics -> %s", args.output)
    return 0


def cmd_noise(args: argparse.Namespace) -> int:
    from imply.paper.results import write_result
    from imply.study.section4.config import NoiseConfig
    from imply.study.section4.scoring import noise_sweep

    result = noise_sweep(
        _table(args),
        _csv(args.truth),
        _csv(args.rollouts),
        settings=config_from_json(NoiseConfig, args.noise_json, "--noise-json"),
        seed=args.seed,
        score=_score(args),
    )
    write_result(args.output, noise_sweep, result)
    log.info("noise sweep -> %s", args.output)
    return 0


def cmd_selection(args: argparse.Namespace) -> int:
    from imply.io import write_csv
    from imply.paper.results import write_result
    from imply.study.section4.config import SelectionConfig
    from imply.study.section4.selection import selection_study

    result, choices = selection_study(
        _table(args),
        _csv(args.truth),
        _csv(args.rollouts),
        settings=config_from_json(SelectionConfig, args.selection_json, "--selection-json"),
        seed=args.seed,
        score=_score(args),
    )
    write_csv(args.choices, choices)
    write_result(args.output, selection_study, result)
    log.info("selection -> %s", args.output)
    return 0


def cmd_through_evaluate(args: argparse.Namespace) -> int:
    from imply.evaluate.config import EvaluateConfig
    from imply.evaluate.report import write_report
    from imply.evaluate.suite import SuiteError
    from imply.paper.results import write_result
    from imply.study.section4.through_evaluate import known_answers, run_standins

    settings = config_from_json(EvaluateConfig, args.evaluate_json, "--evaluate-json")
    score = _score(args)
    with user_errors(SuiteError, message="--suite: {error}"):
        evaluations = run_standins(args.suite, settings=settings, score=score, progress=not args.no_progress)
    write_report(evaluations, args.report, force=True)
    write_result(args.output, known_answers, known_answers(evaluations))
    log.info("stand-ins through imply evaluate: report -> %s, known answers -> %s", args.report, args.output)
    return 0
