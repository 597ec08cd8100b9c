"""``imply study pixel train|score|figure``: the pixel-space, stochastic world model beyond the paper.

Typical use (what ``workflow/rules/pixel.smk`` runs; the evaluation between is ``imply evaluate``
with ``--model imply.models.pixel_video:trained_pixel_video,checkpoint=...``)::

    imply study pixel train --clips results/clips/train.npz --recipe-json '{"epochs": 20, ...}' --variant calib \\
        -o results/pixel/calib/model.pt --history results/pixel/calib/training.json
    imply study pixel score --calib results/pixel/evaluate/calib --nocalib results/pixel/evaluate/nocalib \\
        --calib-history results/pixel/calib/training.json --nocalib-history results/pixel/nocalib/training.json \\
        -o results/pixel/metrics.json
    imply study pixel figure --metrics results/pixel/metrics.json --calib-model results/pixel/calib/model.pt \\
        --calib results/pixel/evaluate/calib/per_object.csv --nocalib results/pixel/evaluate/nocalib/per_object.csv \\
        --suite results/suite --pdf results/paper/figures/figure3.pdf --png results/paper/figures/figure3.png
"""

from __future__ import annotations

import argparse
import json
import logging
from pathlib import Path

from imply.cli.common import UserError, config_from_json, existing_file, int_range, json_arg, output_file, user_errors

log = logging.getLogger("imply.pixel")


def register(sub: argparse._SubParsersAction) -> None:
    pixel = sub.add_parser("pixel", help="the pixel-space, stochastic world model (beyond the paper)")
    psub = pixel.add_subparsers(dest="pixel_command", required=True)

    tr = psub.add_parser("train", help="train one variant on a clip split")
    tr.add_argument("--clips", type=existing_file, required=True, help="results/clips/train.npz (and its .csv)")
    tr.add_argument("--recipe-json", type=json_arg, default={}, help="the recipe (config pixel.recipe)")
    tr.add_argument(
        "--variant",
        choices=("calib", "nocalib"),
        required=True,
        help="calib: the object's two calibration pushes in context; nocalib: none",
    )
    tr.add_argument("--threads", type=int_range(1), default=2, help="torch threads")
    tr.add_argument("--history", help="also write the per-epoch losses and seconds here (.json)")
    tr.add_argument("--no-progress", action="store_true", help="no progress bar")
    tr.add_argument("-o", "--output", required=True, help="the checkpoint to write (.pt)")
    tr.set_defaults(func=cmd_train)

    sc = psub.add_parser("score", help="the result document of both variants' imply evaluate reports")
    sc.add_argument("--calib", required=True, help="the calibrated variant's report folder (conditions own, other)")
    sc.add_argument("--nocalib", required=True, help="the report folder of the variant without calibration (none)")
    sc.add_argument(
        "--calib-history", type=existing_file, required=True, help="the calibrated variant's training history (.json)"
    )
    sc.add_argument(
        "--nocalib-history", type=existing_file, required=True, help="the other variant's training history (.json)"
    )
    sc.add_argument("-o", "--output", required=True, help="the result document to write (results/pixel/metrics.json)")
    sc.set_defaults(func=cmd_score)

    fg = psub.add_parser("figure", help="Figure 3 as PDF and PNG")
    fg.add_argument("--metrics", type=existing_file, required=True, help="results/pixel/metrics.json")
    fg.add_argument("--calib-model", type=existing_file, required=True, help="the calibrated variant's checkpoint")
    fg.add_argument("--calib", type=existing_file, required=True, help="its report's per_object.csv")
    fg.add_argument("--nocalib", type=existing_file, required=True, help="the other variant's per_object.csv")
    fg.add_argument("--suite", required=True, help="the suite folder both were evaluated on")
    fg.add_argument("--objects", type=int_range(1, 8), default=2, help="objects shown in panel (a)")
    fg.add_argument("--pdf", required=True, help="the figure to write as PDF")
    fg.add_argument("--png", required=True, help="the figure to write as PNG")
    fg.set_defaults(func=cmd_figure)


def cmd_train(args: argparse.Namespace) -> int:
    from imply.data.clips import load_clips
    from imply.io import write_json
    from imply.models.pixel_video import PixelVideoConfig, save_pixel_video, train_pixel_video

    cfg = config_from_json(PixelVideoConfig, args.recipe_json, "--recipe-json")
    out = output_file(args.output, [args.clips])
    history_path = output_file(args.history, [args.clips], "--history") if args.history else None
    with user_errors(ValueError, KeyError, message=f"--clips {args.clips}: {{error}}"):
        frames, meta = load_clips(args.clips)
    if max(cfg.frames) >= frames.shape[1]:
        raise UserError(f"--recipe-json frames: index {max(cfg.frames)} is past the clips' {frames.shape[1]} frames")
    with user_errors(ValueError, message=f"--clips {args.clips}: {{error}}"):
        model, history = train_pixel_video(
            frames, meta, cfg, calibrated=args.variant == "calib", threads=args.threads, progress=not args.no_progress
        )
    save_pixel_video(out, model, history)
    if history_path:
        write_json(history_path, {"variant": args.variant, "recipe": cfg.to_dict(), "epochs": history})
    log.info("%s: %d epochs in %.0f s -> %s", args.variant, len(history), sum(h["seconds"] for h in history), out)
    return 0


def _history(path: Path) -> list[dict]:
    try:
        doc = json.loads(Path(path).read_text())
        return list(doc["epochs"])
    except (ValueError, KeyError, TypeError) as exc:
        raise UserError(f"{path}: not a training history of imply study pixel train ({exc})") from exc


def cmd_score(args: argparse.Namespace) -> int:
    from imply.paper.results import write_result
    from imply.study.pixel_model import pixel_metrics

    out = output_file(args.output, [args.calib_history, args.nocalib_history])
    with user_errors(ValueError, KeyError):
        result = pixel_metrics(
            calib=args.calib,
            nocalib=args.nocalib,
            calib_history=_history(args.calib_history),
            nocalib_history=_history(args.nocalib_history),
        )
    write_result(out, pixel_metrics, result)
    return 0


def cmd_figure(args: argparse.Namespace) -> int:
    import numpy as np
    import pandas as pd

    from imply.evaluate.harness import make_request
    from imply.evaluate.suite import load_suite, load_truth
    from imply.models.pixel_video import trained_pixel_video
    from imply.paper.figures import figure3
    from imply.paper.results import read_result

    with user_errors(ValueError, KeyError, OSError, message="{error}"):
        suite = load_suite(args.suite)
        truth = load_truth(suite)
        model = trained_pixel_video(checkpoint=args.calib_model)
        _, metrics = read_result(args.metrics)
    n = min(args.objects, len(suite.object_ids))
    k = len(suite.query_speeds)
    speeds = sorted({0, k // 2, k - 1})
    index = np.arange(n)
    generated = model.rollout(make_request(suite, index, condition="own", sample=0))[:, :, -1]
    true_rest = np.concatenate([truth.rest_frames[i, speeds] for i in index])
    gen_rest = np.concatenate([generated[i, speeds] for i in index])
    labels = [
        f"{str(suite.object_ids[i]).rsplit('-', 1)[-1]}\n{suite.query_speeds[s]:g} m/s" for i in index for s in speeds
    ]
    calib = pd.read_csv(args.calib, dtype={"object_id": str})
    nocalib = pd.read_csv(args.nocalib, dtype={"object_id": str})
    slides = {
        "calibrated, own calibration (sample 0)": calib[(calib["condition"] == "own") & (calib["sample"] == 0)],
        "no calibration (sample 0)": nocalib[nocalib["sample"] == 0],
    }
    figure3(
        true_rest=true_rest,
        generated_rest=gen_rest,
        panel_labels=labels,
        slides=slides,
        selection=metrics["nocalib"]["selection"],
        pdf_path=args.pdf,
        png_path=args.png,
    )
    return 0
