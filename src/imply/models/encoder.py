"""The frozen frame encoder of the Section 5 study: one interface, three ways to get one.

Interface: :class:`FrameEncoder`. ``encoder.encode(frames)`` takes uint8 RGB frames
(N, H, W, 3) and returns float32 patch tokens (N, n_patches, dim), tokens in row-major
patch order over the grid ``encoder.grid`` = (rows, columns). As V-JEPA 2-AC does,
every frame is encoded on its own: scaled to [0, 1], resized to the encoder's input
size if it differs, normalised with the ImageNet mean and std, and duplicated to fill
the 2-frame tubelet, so each frame gives one time step of tokens.

Implementations (config ``encoder.kind``):

* ``cpu`` (default): a small ViT of the V-JEPA 2 family (:mod:`imply.models.vision_transformer`,
  preset ``tiny``: 16 x 16 tubelet patches of 2 frames, RoPE, 4 blocks of width 64),
  pretrained inside the workflow with a JEPA objective on frames of the ``pretrain``
  split (:mod:`imply.models.pretrain`) and then frozen. It stands in for V-JEPA 2's
  ViT-g (1B parameters), which cannot be run over the whole study on 2 CPU cores. Its
  weights file is ``results/encoder/encoder.pt``.
* ``vjepa2_hf``: released V-JEPA 2 weights in the Hugging Face ``VJEPA2Model`` directory
  format (``config.json`` + ``model.safetensors``, e.g. a local download of
  ``facebook/vjepa2-vitg-fpc64-256``), loaded with ``transformers`` from
  ``encoder.weights`` with ``local_files_only`` (nothing is downloaded at run time).
  Needs the optional extra ``pip install imply[vjepa2]``. Frames are resized to the
  model's square ``crop_size``.
* ``vjepa2_pt``: an official V-JEPA 2 ``.pt`` checkpoint (e.g. ``vitg.pt``) at
  ``encoder.weights``: the state dict under ``encoder.checkpoint_key``
  (``target_encoder`` by default, else ``encoder``), ``module.`` and ``backbone.``
  prefixes stripped, loaded strictly into the architecture ``encoder.arch``
  (``vit_giant_xformers`` for ViT-g) at ``encoder.input_size`` (256 x 256).

To switch the study to the real encoder, download the weights once, then set e.g.::

    encoder:
      kind: vjepa2_pt
      weights: /data/vjepa2/vitg.pt
      arch: vit_giant_xformers
      input_size: [256, 256]
      pool_grid: [4, 4]        # keep the cached features small

and rerun ``snakemake`` (the encode rule asks for a GPU then; ``encoder.device``, default
``auto``, uses CUDA when there is one).

Cached features (:func:`encode_clips`, :func:`save_features`), one file per clip split, ``results/features/<split>.npz``:

    ``tokens``   float16 (n_clips, T, n_patches, dim): frame t of clip i -> tokens[i, t];
                 T = 8 frames as in ``results/clips/<split>.npz``; patches row-major over
                 ``grid`` (2 x 8 = 16 patches of dim 64 with the CPU default)
    ``clip_id``  int64 (n_clips,): the clips' ids, rows in the same order as the clips CSV
    ``grid``     int64 (2,): patch rows and columns
    ``encoder``  str: the encoder's description

``encoder.pool_grid`` (optional) average-pools each frame's patch grid to that size before
caching (needed for ViT-g, whose 16 x 16 x 1408 tokens per frame are too large to cache),
with the one pooling of :func:`imply.models.features.pool_tokens` (each side of the
encoder's grid a multiple of the pooled one).
"""

from __future__ import annotations

import io
import logging
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch
from torch import nn
from tqdm.auto import tqdm

from imply.io import write_npz
from imply.models.config import PRESETS, ViTConfig
from imply.models.features import pool_tokens
from imply.models.pretrain import PretrainConfig
from imply.models.vision_transformer import VisionTransformer, preprocess
from imply.options import Config, option

log = logging.getLogger("imply.encoder")

KINDS = ("cpu", "vjepa2_hf", "vjepa2_pt")
CPU_FORMAT = "imply-cpu-encoder-v1"


class EncoderError(ValueError):
    """A weights path or checkpoint that cannot be used; the message says why."""


@dataclass(frozen=True, kw_only=True)
class EncoderConfig(Config):
    """Config section ``encoder`` (see the module docstring for the kinds)."""

    config_key: ClassVar[str] = "encoder"

    kind: str = option("cpu", doc="cpu (pretrained here) | vjepa2_hf | vjepa2_pt", choices=KINDS, required=True)
    weights: str | None = option(None, doc="local path for vjepa2_hf / vjepa2_pt (never downloaded)")
    arch: str | ViTConfig = option(
        "vit_giant_xformers", doc="vjepa2_pt architecture: a preset name or ViTConfig fields", choices=tuple(PRESETS)
    )
    input_size: tuple[int, int] = option((256, 256), doc="vjepa2_pt input size (px)", items={"minimum": 16})
    checkpoint_key: str = option("target_encoder", doc="vjepa2_pt weights key", choices=("target_encoder", "encoder"))
    pool_grid: tuple[int, int] | None = option(
        None, doc="pool cached tokens to this (rows, columns) grid", items={"minimum": 1}
    )
    batch_size: int = option(256, doc="frames per encoder batch", minimum=1)
    device: str = option("auto", doc="torch device (auto: CUDA when available)")
    cpu_arch: str | ViTConfig = option(
        "tiny", doc="the CPU default: a preset name or ViTConfig fields", choices=tuple(PRESETS)
    )
    pretrain: PretrainConfig = option(PretrainConfig(), doc="the CPU default's JEPA pretraining")

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"encoder.kind {self.kind!r} is not one of {', '.join(KINDS)}")

    def cpu_architecture(self) -> ViTConfig:
        """The CPU default's architecture: preset ``cpu_arch`` or a mapping of :class:`ViTConfig` fields."""
        if isinstance(self.cpu_arch, dict):
            return ViTConfig.from_dict(self.cpu_arch, "encoder.cpu_arch")
        if self.cpu_arch not in PRESETS:
            raise ValueError(f"encoder.cpu_arch {self.cpu_arch!r} is not one of {', '.join(PRESETS)}")
        return PRESETS[self.cpu_arch]


class FrameEncoder:
    """A frozen encoder of single frames; subclasses provide :meth:`_tokens`."""

    name: str = "encoder"

    device: torch.device = torch.device("cpu")

    def __init__(self, input_size: tuple[int, int], patch_size: int, dim: int, tubelet: int = 2) -> None:
        self.input_size = (int(input_size[0]), int(input_size[1]))
        self.patch_size = int(patch_size)
        self.dim = int(dim)
        self.tubelet = int(tubelet)

    def to(self, device: str | torch.device) -> FrameEncoder:
        """Run on ``device`` ('auto': CUDA when available)."""
        if str(device) == "auto":
            device = "cuda" if torch.cuda.is_available() else "cpu"
        self.device = torch.device(device)
        self.model.to(self.device)
        return self

    @property
    def grid(self) -> tuple[int, int]:
        return self.input_size[0] // self.patch_size, self.input_size[1] // self.patch_size

    @property
    def n_patches(self) -> int:
        return self.grid[0] * self.grid[1]

    def _tokens(self, x: torch.Tensor) -> torch.Tensor:
        raise NotImplementedError

    @torch.no_grad()
    def encode(self, frames: np.ndarray) -> torch.Tensor:
        """uint8 (N, H, W, 3) frames -> float32 (N, n_patches, dim) patch tokens."""
        frames = np.asarray(frames)
        if frames.ndim != 4 or frames.shape[-1] != 3 or frames.dtype != np.uint8:
            raise ValueError(f"frames must be uint8 (N, H, W, 3), got {frames.dtype} {frames.shape}")
        x = preprocess(frames, self.input_size, self.tubelet).to(self.device)
        out = self._tokens(x).float().cpu()
        if out.shape[1:] != (self.n_patches, self.dim):
            raise EncoderError(
                f"{self.name}: got tokens {tuple(out.shape)}, expected (N, {self.n_patches}, {self.dim})"
            )
        return out


class ViTFrameEncoder(FrameEncoder):
    """Our V-JEPA 2-family ViT (the CPU default, or an official .pt checkpoint)."""

    def __init__(self, model: VisionTransformer, input_size: tuple[int, int], name: str) -> None:
        super().__init__(input_size, model.cfg.patch_size, model.cfg.embed_dim, model.cfg.tubelet_size)
        self.model = model.eval()
        for p in self.model.parameters():
            p.requires_grad_(False)
        self.name = name

    def _tokens(self, x: torch.Tensor) -> torch.Tensor:
        return self.model(x)


class HFFrameEncoder(FrameEncoder):
    """A transformers ``VJEPA2Model`` (encoder only: the predictor is skipped)."""

    def __init__(self, model: nn.Module, name: str) -> None:
        cfg = model.config
        size = int(cfg.crop_size)
        super().__init__((size, size), cfg.patch_size, cfg.hidden_size, cfg.tubelet_size)
        self.model = model.eval()
        self.name = name

    def _tokens(self, x: torch.Tensor) -> torch.Tensor:
        # VJEPA2Model takes (B, T, C, H, W)
        out = self.model(pixel_values_videos=x.permute(0, 2, 1, 3, 4), skip_predictor=True)
        return out.last_hidden_state


def strip_prefixes(state: dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
    """Drop DDP's ``module.`` and the wrapper's ``backbone.`` prefixes from state-dict keys."""
    out = {}
    for key, value in state.items():
        for prefix in ("module.", "backbone."):
            if key.startswith(prefix):
                key = key[len(prefix) :]
        out[key] = value
    return out


def load_vjepa2_pt(
    path: str | os.PathLike, *, arch: str | dict, input_size: tuple[int, int], key: str = "target_encoder"
) -> ViTFrameEncoder:
    """An official V-JEPA 2 ``.pt`` checkpoint as a frozen frame encoder."""
    path = Path(path)
    if not path.is_file():
        raise EncoderError(f"encoder.weights: {path} is not a file (a V-JEPA 2 .pt checkpoint)")
    ckpt = torch.load(path, map_location="cpu", weights_only=True)
    if not isinstance(ckpt, dict):
        raise EncoderError(f"{path}: not a checkpoint dictionary")
    keys = [key] + [k for k in ("target_encoder", "encoder") if k != key]
    found = next((k for k in keys if k in ckpt), None)
    if found is None:
        raise EncoderError(
            f"{path}: no '{key}' (nor target_encoder/encoder) state dict; has {', '.join(map(str, ckpt))}"
        )
    if found != key:
        log.warning("%s: no '%s' weights; using '%s'", path, key, found)
    cfg = _arch(arch)
    model = VisionTransformer(cfg)
    try:
        model.load_state_dict(strip_prefixes(ckpt[found]), strict=True)
    except RuntimeError as exc:
        raise EncoderError(f"{path}: weights do not fit architecture {arch!r}: {str(exc).splitlines()[0]}") from None
    return ViTFrameEncoder(model, input_size, name=f"vjepa2_pt:{path.name}:{found}")


def load_vjepa2_hf(path: str | os.PathLike) -> HFFrameEncoder:
    """A Hugging Face ``VJEPA2Model`` directory (config.json + weights) as a frozen frame encoder."""
    path = Path(path)
    if not (path / "config.json").is_file():
        raise EncoderError(f"encoder.weights: {path} is not a Hugging Face model directory (no config.json)")
    try:
        from transformers import VJEPA2Model
    except ImportError:
        raise EncoderError("encoder.kind vjepa2_hf needs transformers: pip install 'imply[vjepa2]'") from None
    model = VJEPA2Model.from_pretrained(str(path), local_files_only=True)
    return HFFrameEncoder(model, name=f"vjepa2_hf:{path.name}")


def _arch(arch: str | dict) -> ViTConfig:
    if isinstance(arch, dict):
        return ViTConfig.from_dict(arch)
    if arch not in PRESETS:
        raise EncoderError(f"encoder.arch {arch!r} is not one of {', '.join(PRESETS)}")
    return PRESETS[arch]


def save_cpu_encoder(
    path: str | os.PathLike, model: VisionTransformer, *, input_size: tuple[int, int], extra: dict | None = None
) -> None:
    """Write the CPU default's weights file (the frozen target encoder and its architecture)."""
    from imply.io import atomic_path

    payload = {
        "format": CPU_FORMAT,
        "arch": model.cfg.to_dict(),
        "input_size": list(input_size),
        "encoder": {k: v.detach().clone() for k, v in model.state_dict().items()},
        "extra": extra or {},
    }
    # torch names the archive after the file it writes; through a buffer, the same weights give the same bytes
    buf = io.BytesIO()
    torch.save(payload, buf)
    with atomic_path(path) as tmp:
        tmp.write_bytes(buf.getvalue())


def load_cpu_encoder(path: str | os.PathLike) -> ViTFrameEncoder:
    """The CPU default encoder written by ``imply study encoder pretrain``."""
    path = Path(path)
    if not path.is_file():
        raise EncoderError(f"{path}: no such encoder file (run 'imply study encoder pretrain')")
    ckpt = torch.load(path, map_location="cpu", weights_only=True)
    if not isinstance(ckpt, dict) or ckpt.get("format") != CPU_FORMAT:
        raise EncoderError(f"{path}: not an imply CPU encoder file")
    model = VisionTransformer(ViTConfig.from_dict(ckpt["arch"]))
    model.load_state_dict(ckpt["encoder"], strict=True)
    return ViTFrameEncoder(model, tuple(ckpt["input_size"]), name=f"cpu:{path.name}")


def load_encoder(cfg: EncoderConfig, weights: str | os.PathLike | None = None) -> FrameEncoder:
    """The encoder of config section ``encoder``; ``weights`` overrides ``encoder.weights``.

    For ``kind: cpu`` the weights are the pretrained file (``results/encoder/encoder.pt``).
    """
    path = weights if weights is not None else cfg.weights
    if path is None:
        raise EncoderError(f"encoder.kind {cfg.kind}: no weights path (encoder.weights)")
    if cfg.kind == "cpu":
        enc: FrameEncoder = load_cpu_encoder(path)
    elif cfg.kind == "vjepa2_hf":
        enc = load_vjepa2_hf(path)
    else:
        enc = load_vjepa2_pt(path, arch=cfg.arch, input_size=cfg.input_size, key=cfg.checkpoint_key)
    return enc.to(cfg.device)


def encode_clips(
    encoder: FrameEncoder,
    frames: np.ndarray,
    *,
    batch_size: int = 256,
    pool_grid: tuple[int, int] | None = None,
    progress: bool = True,
    desc: str = "encode",
) -> tuple[np.ndarray, tuple[int, int]]:
    """Encode clips (n_clips, T, H, W, 3) uint8 -> (float16 tokens (n_clips, T, n_patches, dim), grid).

    With ``pool_grid`` each frame's tokens are pooled to it (:func:`imply.models.features.pool_tokens`)
    before they are cached.
    """
    n, t = frames.shape[:2]
    flat = frames.reshape(n * t, *frames.shape[2:])
    out = None
    grid = encoder.grid if pool_grid is None else (int(pool_grid[0]), int(pool_grid[1]))
    t0 = time.perf_counter()
    bar = tqdm(total=n * t, desc=desc, unit="frame", disable=not progress, mininterval=2.0)
    for lo in range(0, n * t, batch_size):
        tok = encoder.encode(flat[lo : lo + batch_size]).numpy()
        if grid != encoder.grid:
            tok = pool_tokens(tok[:, None], encoder.grid, grid)[:, 0]  # each frame a one-frame clip
        if out is None:
            out = np.zeros((n * t, tok.shape[1], tok.shape[2]), dtype=np.float16)
        out[lo : lo + len(tok)] = tok.astype(np.float16)
        bar.update(len(tok))
    bar.close()
    dt = time.perf_counter() - t0
    log.info("%s: encoded %d frames in %.1f s (%.0f frames/s)", desc, n * t, dt, n * t / max(dt, 1e-9))
    assert out is not None
    return out.reshape(n, t, out.shape[1], out.shape[2]), grid


def save_features(
    path: str | os.PathLike, tokens: np.ndarray, *, clip_id: np.ndarray, grid: tuple[int, int], name: str
) -> None:
    """Write a features file (layout in the module docstring)."""
    write_npz(
        path,
        tokens=tokens.astype(np.float16),
        clip_id=np.asarray(clip_id, dtype=np.int64),
        grid=np.asarray(grid, dtype=np.int64),
        encoder=np.asarray(name),
    )


def load_features(path: str | os.PathLike) -> dict[str, Any]:
    """A features file: dict with tokens (float16), clip_id, grid (tuple) and encoder (str)."""
    with np.load(path) as z:
        return {
            "tokens": z["tokens"],
            "clip_id": z["clip_id"],
            "grid": tuple(int(g) for g in z["grid"]),
            "encoder": str(z["encoder"]),
        }
