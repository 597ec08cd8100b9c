"""``imply study clips render``: one split of rendered push clips (frames and metadata) for the Section 5 study."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

from imply.cli.common import UserError, config_from_json, int_range, json_arg

log = logging.getLogger("imply")


def register(sub: argparse._SubParsersAction) -> None:
    c = sub.add_parser("clips", help="rendered push clips (paper Section 5 data)")
    csub = c.add_subparsers(dest="clips_command", required=True)
    r = csub.add_parser("render", help="simulate and render one split of clips: frames (.npz) and metadata (.csv)")
    r.add_argument("--split", required=True, help="train | heldout_calib | heldout_nocalib | pretrain | validation")
    r.add_argument("--clips-json", type=json_arg, required=True, help="config section 'clips' as JSON")
    r.add_argument("--score-json", type=json_arg, required=True, help="calibration_speeds and query_speeds as JSON")
    r.add_argument("--scene-json", type=json_arg, help="config section 'scene' as JSON")
    r.add_argument("--threads", type=int_range(1), default=1, help="simulation threads")
    r.add_argument(
        "-o",
        "--output",
        required=True,
        help="the split's frames (.npz); its pushes' table is written beside it, with the suffix .csv",
    )
    r.set_defaults(func=cmd_render)


def cmd_render(args: argparse.Namespace) -> int:
    from imply.data.clips import SPLITS, ClipsConfig, render_split, save_split
    from imply.score import ScoreConfig
    from imply.sim import SceneConfig

    if args.split not in SPLITS:
        raise UserError(f"--split {args.split!r} is not one of {', '.join(SPLITS)}")
    if Path(args.output).suffix != ".npz":
        raise UserError(f"-o {args.output}: the frames file must end in .npz (its .csv is written beside it)")
    cfg = config_from_json(ClipsConfig, args.clips_json, "--clips-json")
    speeds = config_from_json(ScoreConfig, args.score_json, "--score-json")
    scene = config_from_json(SceneConfig, args.scene_json, "--scene-json")
    frames, meta = render_split(cfg, args.split, scene=scene, speeds=speeds, nthread=args.threads)
    save_split(args.output, Path(args.output).with_suffix(".csv"), frames=frames, meta=meta, cfg=cfg)
    return 0
