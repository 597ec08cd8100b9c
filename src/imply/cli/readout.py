"""``imply study readout fit``: both displacement readouts fitted on training clips and evaluated on held-out objects."""

from __future__ import annotations

import argparse
import logging

from imply.cli.common import config_from_json, existing_file, int_range, json_arg, user_errors

log = logging.getLogger("imply")


def register(sub: argparse._SubParsersAction) -> None:
    ro = sub.add_parser("readout", help="displacement readouts: ridge from features, frame differences from pixels")
    rsub = ro.add_subparsers(dest="readout_command", required=True)
    f = rsub.add_parser("fit", help="fit both readouts on training clips, evaluate on held-out objects")
    f.add_argument(
        "--train",
        nargs=3,
        required=True,
        type=existing_file,
        metavar=("FRAMES", "METADATA", "FEATURES"),
        help="the training split's frames (.npz), metadata (.csv) and encoder features (.npz)",
    )
    f.add_argument(
        "--heldout",
        nargs=3,
        action="append",
        required=True,
        type=existing_file,
        metavar=("FRAMES", "METADATA", "FEATURES"),
        help="a held-out split's three files (repeatable)",
    )
    f.add_argument("--readout-json", type=json_arg, default={}, help="config section 'readout' as JSON")
    f.add_argument(
        "--pretrain-episodes",
        type=int_range(0),
        default=0,
        help="episodes the encoder was pretrained on (config clips.n_pretrain_episodes), reported",
    )
    f.add_argument("-o", "--output", required=True, help="fitted ridge readout (.npz)")
    f.add_argument("--metrics", required=True, help="the evaluation, a result document (JSON)")
    f.set_defaults(func=cmd_fit)


def cmd_fit(args: argparse.Namespace) -> int:
    from imply.paper.results import write_result
    from imply.readout import ReadoutConfig
    from imply.study.readout_evaluation import clip_files, evaluate_readouts

    settings = config_from_json(ReadoutConfig, args.readout_json, "--readout-json")
    with user_errors(ValueError):
        ridge, result = evaluate_readouts(
            clip_files(*args.train),
            [clip_files(*files) for files in args.heldout],
            settings=settings,
            pretrain_episodes=args.pretrain_episodes,
        )
    ridge.save(args.output)
    write_result(args.metrics, evaluate_readouts, result)
    return 0
