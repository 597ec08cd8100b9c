"""``imply study model train|readout|rollout|plot``: the action-conditioned predictor of Section 5 on cached encoder features.

Typical use (what ``workflow/rules/model.smk`` runs)::

    imply study model readout --features results/features/train.npz --clips results/clips/train.csv \\
        --token-grid 1 8 -o results/model/readout_ln.npz --report results/model/readout_ln.json
    imply study model train --features results/features/train.npz --clips results/clips/train.csv \\
        --readout results/model/readout_ln.npz --preset-json '{"width": 64, ...}' --token-grid 1 8 \\
        --variant-json '{"calib": true, ...}' --train-json '{...}' --rest-state 1.0 --seed 0 \\
        -o results/model/calib/seed0/model.pt --history results/model/calib/seed0/training.json \\
        --rollout-readout results/model/calib/seed0/readout.npz
    imply study model rollout --model results/model/calib/seed0/model.pt --features results/features/heldout_calib.npz \\
        --clips results/clips/heldout_calib.csv --readout results/model/calib/seed0/readout.npz \\
        --contexts own,swap,none --derangement-seed 11 -o results/model/calib/seed0/rollouts.csv
    imply study model plot results/model/*/seed*/training.json -o results/model/training.png

A training run with a checkpoint beside its output resumes from it.
"""

from __future__ import annotations

import argparse
import logging
import time
from dataclasses import replace
from pathlib import Path

from imply.cli.common import UserError, config_from_json, existing_file, int_range, json_arg, output_file, user_errors
from imply.models.config import ModelConfig
from imply.options import default_of

log = logging.getLogger("imply.model")


def register(sub: argparse._SubParsersAction) -> None:
    model = sub.add_parser("model", help="train and roll out the action-conditioned predictor (Section 5)")
    msub = model.add_subparsers(dest="model_command", required=True)

    tr = msub.add_parser("train", help="fine-tune the predictor on cached encoder features")
    tr.add_argument("--features", type=existing_file, required=True, help="results/features/train.npz")
    tr.add_argument("--clips", type=existing_file, required=True, help="results/clips/train.csv")
    tr.add_argument("--preset-json", type=json_arg, required=True, help="the predictor's size (config model.presets.X)")
    tr.add_argument(
        "--variant-json", type=json_arg, required=True, help="the sequence layout (config model.variants.X)"
    )
    tr.add_argument(
        "--train-json",
        type=json_arg,
        required=True,
        help="training settings (config model.train; a layout without calibration trains context_free_epochs, "
        "15 unless given, null: epochs)",
    )
    tr.add_argument(
        "--rest-state",
        type=float,
        default=default_of(ModelConfig, "rest_state"),
        help="state token of the last frame (config model.rest_state)",
    )
    tr.add_argument("--seed", type=int_range(0), required=True, help="data-order seed")
    _add_token_grid(tr, "pool the encoder's patch tokens to this grid (config model.token_grid; default: keep)")
    tr.add_argument(
        "--validation",
        nargs=2,
        type=existing_file,
        metavar=("FEATURES", "CLIPS"),
        help="the validation split (results/features/validation.npz, results/clips/validation.csv): every Table 3 "
        "quantity on it after every epoch (needs --readout and --table)",
    )
    tr.add_argument(
        "--readout",
        type=existing_file,
        help="the latent readout fitted on real training clips (imply study model readout), for validation",
    )
    tr.add_argument("--table", type=existing_file, help="the push table (results/table/table.npz), for validation")
    tr.add_argument("--score-json", type=json_arg, default={}, help="scoring settings (config score): grid, floor")
    tr.add_argument(
        "--derangement-seed",
        type=int_range(0),
        default=default_of(ModelConfig, "derangement_seed"),
        help="which validation object's calibration each object gets in the swap context",
    )
    tr.add_argument("--history", help="also write the per-epoch losses and validation metrics here (.json)")
    tr.add_argument("--threads", type=int_range(1), default=2, help="torch threads")
    tr.add_argument("--checkpoint", help="checkpoint path (default: beside the output, checkpoint.pt)")
    tr.add_argument("--device", default=default_of(ModelConfig, "device"), help="torch device (cpu, cuda)")
    tr.add_argument("-o", "--output", required=True, help="the trained predictor to write (.pt)")
    tr.set_defaults(func=cmd_train)

    rd = msub.add_parser("readout", help="fit the ridge readout on layer-normed last-frame tokens")
    rd.add_argument(
        "--features",
        type=existing_file,
        required=True,
        help="the encoder's features of the training clips (results/features/train.npz)",
    )
    rd.add_argument(
        "--clips", type=existing_file, required=True, help="the training clips' table (results/clips/train.csv)"
    )
    rd.add_argument(
        "--heldout",
        nargs=2,
        action="append",
        default=[],
        metavar=("FEATURES", "CLIPS"),
        type=existing_file,
        help="held-out split to report R^2 on (repeatable)",
    )
    _add_token_grid(rd, "pool the patch tokens to this grid first, as the predictor sees them")
    rd.add_argument("-o", "--output", required=True, help="the fitted readout (.npz)")
    rd.add_argument("--report", required=True, help="its alpha, range and held-out R^2 (.json)")
    rd.set_defaults(func=cmd_readout)

    ro = msub.add_parser("rollout", help="deterministic latent rollouts of held-out objects, read out to displacement")
    ro.add_argument(
        "--model", type=existing_file, required=True, help="the trained predictor (.pt of imply study model train)"
    )
    ro.add_argument("--features", type=existing_file, required=True, help="the held-out clips' encoder features (.npz)")
    ro.add_argument("--clips", type=existing_file, required=True, help="the held-out clips' table (.csv)")
    ro.add_argument(
        "--readout", type=existing_file, required=True, help="the latent readout (.npz of imply study model readout)"
    )
    ro.add_argument("--contexts", default="own,swap,none", help="comma-separated: own, swap, none")
    ro.add_argument(
        "--derangement-seed",
        type=int_range(0),
        default=default_of(ModelConfig, "derangement_seed"),
        help="which object's calibration each object gets in the swap context",
    )
    ro.add_argument("--rest-state", type=float, default=None, help="default: the model's training value")
    ro.add_argument(
        "--batch-size",
        type=int_range(1),
        default=default_of(ModelConfig, "rollout_batch"),
        help="objects rolled out per batch",
    )
    ro.add_argument("--threads", type=int_range(1), default=2, help="torch threads")
    ro.add_argument("-o", "--output", required=True, help="the rollouts to write (.npz)")
    ro.set_defaults(func=cmd_rollout)

    pl = msub.add_parser("plot", help="plot the per-epoch validation of trained predictors")
    pl.add_argument(
        "histories", nargs="+", type=existing_file, help="training.json files (imply study model train --history)"
    )
    pl.add_argument("-o", "--output", required=True, help="the figure (.png)")
    pl.set_defaults(func=cmd_plot)


def _add_token_grid(parser: argparse.ArgumentParser, help: str) -> None:
    parser.add_argument("--token-grid", type=int_range(1), nargs=2, metavar=("ROWS", "COLS"), help=help)


def _setup_torch(threads: int) -> None:
    import torch

    torch.set_num_threads(max(1, threads))
    torch.use_deterministic_algorithms(True, warn_only=True)


def _feature_split(features: Path, clips: Path):
    from imply.models.features import load_feature_split

    with user_errors(ValueError, KeyError):
        return load_feature_split(features, clips)


def _readout(path: Path):
    from imply.models.latent_readout import load_latent_readout

    with user_errors(ValueError, KeyError, message="--readout: {error}"):
        return load_latent_readout(path)


def _validator(args: argparse.Namespace, layout, train_meta, token_grid):
    """Section 5's per-epoch validation on ``--validation``, or None without it."""
    from imply.models.object_blind import typical_slide_of_clips
    from imply.score import ScoreConfig, Scorer
    from imply.study.section5.validation import section5_validator
    from imply.table import PushTable

    if not args.validation:
        return None
    if not args.readout or not args.table:
        raise UserError("--validation needs --readout and --table")
    score = config_from_json(ScoreConfig, args.score_json, "--score-json")
    with user_errors(ValueError, OSError, KeyError, message="--table: {error}"):
        table = PushTable.load(args.table)
    split = _feature_split(*args.validation).pooled(token_grid)
    readout = _readout(args.readout)
    return section5_validator(
        split,
        layout,
        readout=readout,
        scorer=Scorer(table, grid=score.grid, floor=score.readout_floor),
        typical=typical_slide_of_clips(train_meta),
        derangement_seed=args.derangement_seed,
    )


def cmd_train(args: argparse.Namespace) -> int:
    from imply.io import write_json
    from imply.models.config import Layout, PredictorPreset, TrainConfig
    from imply.models.train import train_variant

    _setup_torch(args.threads)
    preset = config_from_json(PredictorPreset, args.preset_json, "--preset-json")
    # config keeps rest_state beside the variants (one value for all); it belongs to the layout
    layout = replace(config_from_json(Layout, args.variant_json, "--variant-json"), rest_state=args.rest_state)
    config = config_from_json(TrainConfig, args.train_json, "--train-json")
    split = _feature_split(args.features, args.clips)
    grid = tuple(args.token_grid) if args.token_grid else None
    with user_errors(ValueError, message="--token-grid: {error}"):
        validate = _validator(args, layout, split.meta, grid)
    # every output checked before training: a bad path found after minutes of training loses them
    inputs = [args.features, args.clips, args.readout, args.table, *(args.validation or [])]
    out = output_file(args.output, inputs)
    if args.history:
        output_file(args.history, [*inputs, out], option="--history")
    t0 = time.perf_counter()
    with user_errors(ValueError):
        payload = train_variant(
            split,
            preset=preset,
            layout=layout,
            config=config,
            data_seed=args.seed,
            out=out,
            checkpoint=Path(args.checkpoint) if args.checkpoint else out.with_name("checkpoint.pt"),
            token_grid=grid,
            validate=validate,
            device=args.device,
        )
    if args.history:
        write_json(args.history, {"seed": args.seed, "layout": layout.to_dict(), "history": payload["history"]})
    log.info("trained seed %d in %.1f s -> %s", args.seed, time.perf_counter() - t0, out)
    return 0


def cmd_readout(args: argparse.Namespace) -> int:
    from imply.io import write_json
    from imply.models.latent_readout import fit_latent_readout, latent_readout_report

    grid = tuple(args.token_grid) if args.token_grid else None
    with user_errors(ValueError, message="--token-grid: {error}"):
        readout = fit_latent_readout(_feature_split(args.features, args.clips).pooled(grid))
        heldout = {Path(f).stem: _feature_split(f, c).pooled(grid) for f, c in args.heldout}
    report = latent_readout_report(readout, heldout)
    readout.save(args.output)
    write_json(args.report, report)
    return 0


def cmd_rollout(args: argparse.Namespace) -> int:
    from imply.io import write_csv
    from imply.models.rollout import CONTEXTS, rollout_split
    from imply.models.train import load_model

    _setup_torch(args.threads)
    contexts = tuple(c.strip() for c in args.contexts.split(",") if c.strip())
    bad = [c for c in contexts if c not in CONTEXTS]
    if bad:
        raise UserError(f"--contexts: unknown context {bad[0]!r} ({', '.join(CONTEXTS)})")
    model, layout, payload = load_model(args.model)
    if not layout.calib and any(c != "none" for c in contexts):
        raise UserError("--contexts: a model trained without calibration context only takes 'none'")
    grid = payload.get("token_grid")
    split = _feature_split(args.features, args.clips).pooled(tuple(grid) if grid else None)
    readout = _readout(args.readout)
    if (readout.ridge.n_patches, readout.ridge.dim) != split.tokens.shape[2:]:
        raise UserError(
            f"--readout: it reads {readout.ridge.n_patches} tokens of width {readout.ridge.dim}, the model's"
            f" tokens are {split.tokens.shape[2]} of width {split.tokens.shape[3]} (fit it with the model's --token-grid)"
        )
    if args.rest_state is not None:
        layout = replace(layout, rest_state=args.rest_state)
    t0 = time.perf_counter()
    table = rollout_split(
        model,
        layout,
        split,
        readout=readout,
        contexts=contexts,
        derangement_seed=args.derangement_seed,
        batch_size=args.batch_size,
    )
    write_csv(args.output, table)
    log.info("rollouts written to %s in %.1f s", args.output, time.perf_counter() - t0)
    return 0


def cmd_plot(args: argparse.Namespace) -> int:
    import json

    from imply.paper.figures import training_figure

    docs = []
    for path in args.histories:
        with user_errors(
            ValueError,
            KeyError,
            message=f"{path}: not a training history of imply study model train --history ({{error}})",
        ):
            doc = json.loads(Path(path).read_text())
            if not doc["history"] or "layout" not in doc:
                raise KeyError("history")
        docs.append(doc)
    training_figure(docs, png_path=args.output)
    return 0
