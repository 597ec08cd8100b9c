"""``imply study encoder pretrain|encode``: the frozen frame encoder (the CPU default pretrained here, or released weights)."""

from __future__ import annotations

import argparse
import logging
from pathlib import Path

import numpy as np

from imply.cli.common import config_from_json, existing_file, int_range, json_arg, user_errors

log = logging.getLogger("imply")


def register(sub: argparse._SubParsersAction) -> None:
    e = sub.add_parser("encoder", help="the frozen frame encoder: pretrain the CPU default, encode clips")
    esub = e.add_subparsers(dest="encoder_command", required=True)
    p = esub.add_parser("pretrain", help="JEPA-pretrain the CPU default encoder on the pretrain clips")
    p.add_argument("--clips", type=existing_file, required=True, help="pretrain split frames (.npz)")
    p.add_argument("--encoder-json", type=json_arg, required=True, help="config section 'encoder' as JSON")
    p.add_argument("--threads", type=int_range(1), default=2, help="torch threads")
    p.add_argument("-o", "--output", required=True, help="encoder weights file (.pt)")
    p.set_defaults(func=cmd_pretrain)
    n = esub.add_parser("encode", help="encode every frame of a clip split and cache the patch tokens")
    n.add_argument("--clips", type=existing_file, required=True, help="split frames (.npz)")
    n.add_argument("--encoder-json", type=json_arg, required=True, help="config section 'encoder' as JSON")
    n.add_argument("--weights", help="weights path (overrides encoder.weights; the CPU default's .pt)")
    n.add_argument("--threads", type=int_range(1), default=2, help="torch threads")
    n.add_argument("-o", "--output", required=True, help="features file (.npz)")
    n.set_defaults(func=cmd_encode)


def _set_threads(n: int) -> None:
    import torch

    torch.set_num_threads(max(1, int(n)))


def _load_frames(path: Path) -> np.ndarray:
    with user_errors(OSError, KeyError, ValueError, message=f"{path}: not a clips file with 'frames' ({{error}})"):
        with np.load(path) as z:
            return z["frames"]


def _encoder_config(args: argparse.Namespace):
    from imply.models.encoder import EncoderConfig

    return config_from_json(EncoderConfig, args.encoder_json, "--encoder-json")


def cmd_pretrain(args: argparse.Namespace) -> int:
    from imply.models.encoder import save_cpu_encoder
    from imply.models.pretrain import pretrain_encoder

    _set_threads(args.threads)
    enc = _encoder_config(args)
    with user_errors(ValueError, TypeError, message="bad encoder option: {error}"):
        arch = enc.cpu_architecture()
    frames = _load_frames(args.clips)
    flat = frames.reshape(-1, *frames.shape[2:])
    log.info("pretraining on %d frames of %s", len(flat), args.clips)
    with user_errors(ValueError):
        model, hist = pretrain_encoder(flat, arch, enc.pretrain)
    losses = np.asarray(hist["loss"])
    k = min(50, len(losses))
    save_cpu_encoder(
        args.output,
        model,
        input_size=tuple(flat.shape[1:3]),
        extra={"loss_first": float(losses[:k].mean()), "loss_last": float(losses[-k:].mean()), "steps": len(losses)},
    )
    return 0


def cmd_encode(args: argparse.Namespace) -> int:
    from imply.models.encoder import EncoderError, encode_clips, load_encoder, save_features

    _set_threads(args.threads)
    enc = _encoder_config(args)
    with user_errors(EncoderError):
        encoder = load_encoder(enc, args.weights)
    frames = _load_frames(args.clips)
    with np.load(args.clips) as z:
        clip_id = z["clip_id"]
    tokens, grid = encode_clips(
        encoder, frames, batch_size=enc.batch_size, pool_grid=enc.pool_grid, desc=f"encode {Path(args.clips).stem}"
    )
    save_features(args.output, tokens, clip_id=clip_id, grid=grid, name=encoder.name)
    return 0
