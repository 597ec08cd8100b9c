"""Subcommands of the Section 5 model stage: ``imply model train|readout|rollout`` and ``imply section5``.

Typical use (what the workflow runs; see workflow/rules/model.smk and section5.smk)::

    imply model train --features results/features/train.npz --clips results/clips/train.csv \\
        --model-json '{...config model...}' --variant calib --seed 0 -o results/model/calib/seed0/model.pt
    imply model readout --features results/features/train.npz --clips results/clips/train.csv \\
        -o results/model/readout_ln.npz
    imply model rollout --model results/model/calib/seed0/model.pt --features results/features/heldout_calib.npz \\
        --clips results/clips/heldout_calib.csv --readout results/model/readout_ln.npz \\
        --contexts own,swap,none --derangement-seed 11 -o results/model/calib/seed0/rollouts.csv
    imply section5 --rollouts calib:0:PATH --rollouts nocalib:0:PATH ... --table results/table/table.npz \\
        --score-json '{...}' --model-json '{...}' --out-dir results/section5 ...

``--model-json`` is the config's ``model`` section (preset, presets, variants,
train, ...); a training run with a checkpoint beside its output resumes from it.
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

from imply.cli import UserError, existing_file, json_arg

log = logging.getLogger("imply.model")


def register(sub: argparse._SubParsersAction) -> None:
    """Add this stage's subcommands to the imply parser."""
    model = sub.add_parser("model", help="train and roll out the action-conditioned predictor (Section 5)")
    msub = model.add_subparsers(dest="model_command", required=True)

    tr = msub.add_parser("train", help="fine-tune the predictor on cached encoder features")
    tr.add_argument("--features", type=existing_file, required=True, help="results/features/train.npz")
    tr.add_argument("--clips", type=existing_file, required=True, help="results/clips/train.csv")
    tr.add_argument("--model-json", type=json_arg, required=True, help="the config's model section as JSON")
    tr.add_argument("--variant", required=True, help="a key of model.variants (calib, nocalib)")
    tr.add_argument("--seed", type=int, required=True, help="data-order seed")
    tr.add_argument("--threads", type=int, default=2)
    tr.add_argument("--checkpoint", help="checkpoint path (default: beside the output, checkpoint.pt)")
    tr.add_argument("--device", default="cpu", help="torch device (cpu, cuda)")
    tr.add_argument("-o", "--output", required=True)
    tr.set_defaults(func=cmd_train)

    rd = msub.add_parser("readout", help="fit the ridge readout on layer-normed last-frame tokens")
    rd.add_argument("--features", type=existing_file, required=True)
    rd.add_argument("--clips", type=existing_file, required=True)
    rd.add_argument("--heldout", nargs=2, action="append", default=[], metavar=("FEATURES", "CLIPS"),
                    help="held-out split to report R^2 on (repeatable)")  # fmt: skip
    rd.add_argument("-o", "--output", required=True)
    rd.set_defaults(func=cmd_readout)

    ro = msub.add_parser("rollout", help="deterministic latent rollouts of held-out objects, read out to displacement")
    ro.add_argument("--model", type=existing_file, required=True)
    ro.add_argument("--features", type=existing_file, required=True)
    ro.add_argument("--clips", type=existing_file, required=True)
    ro.add_argument("--readout", type=existing_file, required=True)
    ro.add_argument("--contexts", default="own,swap,none", help="comma-separated: own, swap, none")
    ro.add_argument("--derangement-seed", type=int, default=0)
    ro.add_argument("--rest-state", type=float, default=None, help="default: the model's training value")
    ro.add_argument("--batch-size", type=int, default=100)
    ro.add_argument("--threads", type=int, default=2)
    ro.add_argument("-o", "--output", required=True)
    ro.set_defaults(func=cmd_rollout)

    s5 = sub.add_parser("section5", help="Section 5 scores, Table 3, Figure 2 and the paper part")
    s5.add_argument("--rollouts", action="append", required=True, metavar="MODEL:SEED:PATH",
                    help="a rollout table of model calib|nocalib and data seed SEED (repeatable)")  # fmt: skip
    s5.add_argument("--table", type=existing_file, required=True)
    s5.add_argument("--score-json", type=json_arg, required=True, help="the config's score section")
    s5.add_argument("--selection-seed", type=int, default=0)
    s5.add_argument("--out-dir", required=True, help="results/section5 (metrics.json, per_object.csv)")
    s5.add_argument("--part", required=True, help="results/paper/parts/section5.json")
    s5.add_argument("--table-tex", required=True, help="results/paper/tables/table3.tex")
    s5.add_argument("--figure", required=True, help="figure path without suffix (.pdf and .png are written)")
    s5.set_defaults(func=cmd_section5)


def _setup_torch(threads: int) -> None:
    import torch

    torch.set_num_threads(max(1, threads))
    torch.use_deterministic_algorithms(True, warn_only=True)


def _model_options(cfg: dict, variant: str):
    from imply.models.sequences import Layout
    from imply.models.train import TrainConfig

    try:
        preset = cfg["presets"][cfg["preset"]]
    except KeyError as exc:
        raise UserError(f"--model-json: no preset {cfg.get('preset')!r} in model.presets") from exc
    if variant not in cfg.get("variants", {}):
        raise UserError(f"--variant: {variant!r} is not in model.variants ({', '.join(cfg.get('variants', {}))})")
    try:
        layout = Layout.from_dict(cfg["variants"][variant])
        train_cfg = TrainConfig.from_dict(cfg.get("train", {}))
    except (ValueError, TypeError, KeyError) as exc:
        raise UserError(f"--model-json: {exc}") from exc
    return preset, layout, train_cfg, float(cfg.get("rest_state", 1.0))


def cmd_train(args: argparse.Namespace) -> int:
    from imply.models.ac_predictor import PredictorConfig
    from imply.models.rollout import load_split, training_sequences
    from imply.models.train import train

    _setup_torch(args.threads)
    preset, layout, train_cfg, rest = _model_options(args.model_json, args.variant)
    try:
        split = load_split(args.features, args.clips)
    except (ValueError, KeyError) as exc:
        raise UserError(str(exc)) from exc
    seqs = training_sequences(split, layout, rest)
    try:
        pred_cfg = PredictorConfig.from_dict(
            {**preset, "embed_dim": int(split.tokens.shape[-1]), "grid": split.grid, "max_steps": layout.n_steps}
        )
    except (ValueError, TypeError) as exc:
        raise UserError(f"--model-json: preset: {exc}") from exc
    out = Path(args.output)
    ckpt = Path(args.checkpoint) if args.checkpoint else out.with_name("checkpoint.pt")
    data_key = f"{split.tokens.shape}:{len(seqs)}:{rest}"
    t0 = time.perf_counter()
    train(
        seqs, layout, pred_cfg, train_cfg, args.seed, out, ckpt, data_key=data_key, device=args.device, rest_state=rest
    )
    log.info("trained %s seed %d in %.1f s -> %s", args.variant, args.seed, time.perf_counter() - t0, out)
    return 0


def cmd_readout(args: argparse.Namespace) -> int:
    import numpy as np
    import torch

    from imply.io import write_json
    from imply.models.ac_predictor import normalise_tokens
    from imply.models.rollout import fit_latent_readout, load_split
    from imply.readout import r2_log

    split = load_split(args.features, args.clips)
    readout = fit_latent_readout(split)
    report = {"alpha": readout.ridge.alpha, "log_range": [readout.log_min, readout.log_max], "heldout_r2_log": {}}
    for feats, clips in args.heldout:
        ho = load_split(feats, clips)
        ok = (ho.meta["ok"].to_numpy() == 1) if "ok" in ho.meta.columns else np.ones(len(ho.meta), bool)
        last = normalise_tokens(torch.from_numpy(ho.tokens[ok, -1].astype(np.float32))).numpy()
        r2 = r2_log(ho.meta["displacement"].to_numpy()[ok], readout.predict(last))
        report["heldout_r2_log"][Path(feats).stem] = r2
        log.info("latent readout on %s: held-out R^2 (log slide) %.4f", Path(feats).stem, r2)
    readout.save(args.output)
    write_json(Path(args.output).with_suffix(".json"), report)
    return 0


def cmd_rollout(args: argparse.Namespace) -> int:
    from imply.io import write_csv
    from imply.models.rollout import load_latent_readout, load_split, rollout_split
    from imply.models.train import load_model

    _setup_torch(args.threads)
    contexts = tuple(c.strip() for c in args.contexts.split(",") if c.strip())
    model, layout, payload = load_model(args.model)
    bad = [c for c in contexts if c not in ("own", "swap", "none")]
    if bad:
        raise UserError(f"--contexts: unknown context {bad[0]!r} (own, swap, none)")
    if not layout.calib and any(c != "none" for c in contexts):
        raise UserError("--contexts: a model trained without calibration context only takes 'none'")
    split = load_split(args.features, args.clips)
    try:
        readout = load_latent_readout(args.readout)
    except (ValueError, KeyError) as exc:
        raise UserError(f"--readout: {exc}") from exc
    rest = args.rest_state if args.rest_state is not None else float(payload.get("rest_state", 1.0))
    t0 = time.perf_counter()
    table = rollout_split(
        model, layout, split, readout, contexts,
        rest_state=rest, derangement_seed=args.derangement_seed, batch_size=args.batch_size,
    )  # fmt: skip
    write_csv(args.output, table)
    log.info("rollouts written to %s in %.1f s", args.output, time.perf_counter() - t0)
    return 0


def cmd_section5(args: argparse.Namespace) -> int:
    import pandas as pd

    from imply import section5 as S5
    from imply.io import write_csv, write_json, write_text
    from imply.paper.parts import write_part
    from imply.score import Scorer
    from imply.table import PushTable

    tables = {}
    for spec in args.rollouts:
        try:
            model, seed, path = spec.split(":", 2)
            seed = int(seed)
        except ValueError as exc:
            raise UserError(f"--rollouts: {spec!r} is not MODEL:SEED:PATH") from exc
        if model not in ("calib", "nocalib"):
            raise UserError(f"--rollouts: model {model!r} must be calib or nocalib")
        if not Path(path).is_file():
            raise UserError(f"--rollouts: {path} does not exist")
        tables[(model, seed)] = pd.read_csv(path, dtype={"object_id": str, "context": str, "context_object": str})
    seeds = sorted({s for _, s in tables})
    for s in seeds:
        for m in ("calib", "nocalib"):
            if (m, s) not in tables:
                raise UserError(f"--rollouts: seed {s} lacks the {m} model's rollouts")
    table = PushTable.load(args.table)
    scorer = Scorer(table, grid=int(args.score_json["grid"]), floor=float(args.score_json["readout_floor"]))
    results, per_object = S5.evaluate(tables, scorer, seeds, args.selection_seed)
    nums = S5.numbers(results, seeds)
    claims = S5.claims(results, seeds)
    out = Path(args.out_dir)
    write_json(out / "metrics.json", results)
    write_csv(out / "per_object.csv", per_object)
    write_text(args.table_tex, S5.table3_tex(results, seeds))
    S5.figure2(per_object, seeds[0], f"{args.figure}.pdf", f"{args.figure}.png")
    write_part(args.part, "section5", nums, claims)
    for c in claims:
        log.info("claim %s: %s (%s)", c.id, "holds" if c.holds else "FAILS", c.detail)
    return 0
