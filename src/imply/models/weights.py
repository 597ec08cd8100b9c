"""Released encoder weights checked when the workflow is read, and named as inputs of the DAG.

``encoder.kind: vjepa2_pt`` and ``vjepa2_hf`` read a local weights file (a multi-GB ViT-g
checkpoint) that the workflow does not build. :func:`check_encoder_weights` refuses a path
that is missing or is not a checkpoint of the configured kind before any job runs, without
reading the weights themselves:

* ``vjepa2_pt``: the file is opened with ``torch.load(mmap=True, weights_only=True)``, which
  maps the tensors instead of reading them; the state dict under ``encoder.checkpoint_key``
  (or the other key the loader falls back to) must have exactly the parameter names and
  shapes of ``encoder.arch``, built on PyTorch's ``meta`` device (no memory allocated).
  This is what :func:`imply.models.encoder.load_vjepa2_pt` loads strictly, so a checkpoint
  that passes here loads there.
* ``vjepa2_hf``: the directory holds a ``config.json`` whose ``model_type`` is ``vjepa2``, a
  weights file (safetensors or PyTorch bin, single or sharded), and ``transformers`` is
  installed.

:func:`encoder_weight_files` lists the files that make up the weights, which the encode
rule takes as inputs, so replacing the weights reruns the features and what depends on them.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from imply.models.encoder import EncoderConfig

# the kinds whose weights are a local file given in config (the CPU default is built by the workflow)
RELEASED_KINDS = ("vjepa2_pt", "vjepa2_hf")
# weights files of a Hugging Face model directory: one file, or shards and their index
HF_WEIGHTS_PATTERNS = ("*.safetensors", "*.bin", "*.index.json")
HF_MODEL_TYPE = "vjepa2"


def check_encoder_weights(section: dict[str, Any]) -> None:
    """Refuse ``encoder.weights`` that is missing or not a checkpoint of ``encoder.kind``.

    Raises ValueError with one line naming ``encoder.weights``; does nothing for the CPU default.
    """
    if section.get("kind", "cpu") not in RELEASED_KINDS:
        return  # before importing torch: every `snakemake -n` of the default study passes here
    from imply.models.encoder import EncoderConfig

    cfg = EncoderConfig.from_dict(section)
    if not cfg.weights:
        raise ValueError(f"encoder.weights: encoder.kind {cfg.kind!r} needs a local path to the weights")
    path = Path(cfg.weights)
    if cfg.kind == "vjepa2_pt":
        _check_pt(path, cfg)
    else:
        _check_hf(path)


def encoder_weight_files(section: dict[str, Any]) -> list[str]:
    """The files of released weights (``encoder.weights``) a rule reads; [] for the CPU default."""
    kind, weights = section.get("kind", "cpu"), section.get("weights")
    if kind not in RELEASED_KINDS or not weights:
        return []
    path = Path(weights)
    if kind == "vjepa2_pt":
        return [str(path)]
    files = {path / "config.json"} | {f for pattern in HF_WEIGHTS_PATTERNS for f in path.glob(pattern)}
    return sorted(str(f) for f in files)


def _check_pt(path: Path, cfg: EncoderConfig) -> None:
    import torch

    from imply.models.encoder import strip_prefixes

    what = "a V-JEPA 2 .pt checkpoint"
    if not path.is_file():
        raise ValueError(f"encoder.weights: {path} does not exist ({what}; encoder.kind vjepa2_pt)")
    try:
        ckpt = torch.load(path, map_location="cpu", mmap=True, weights_only=True)
    except Exception as exc:  # torch raises RuntimeError, UnpicklingError, ... for a file that is no checkpoint
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        raise ValueError(f"encoder.weights: {path} does not load as {what} ({first[:200]})") from None
    if not isinstance(ckpt, dict):
        raise ValueError(f"encoder.weights: {path} is not {what} (a {type(ckpt).__name__}, not a dictionary)")
    # the loader's order: the configured key, else the other one
    keys = [cfg.checkpoint_key] + [k for k in ("target_encoder", "encoder") if k != cfg.checkpoint_key]
    found = next((k for k in keys if k in ckpt), None)
    if found is None:
        have = ", ".join(map(str, ckpt)) or "no keys"
        raise ValueError(
            f"encoder.weights: {path} has no '{cfg.checkpoint_key}' state dict (encoder.checkpoint_key; "
            f"nor {' nor '.join(keys[1:])}); it has {have}"
        )
    state = ckpt[found]
    if not isinstance(state, dict):
        raise ValueError(f"encoder.weights: {path}: '{found}' is not a state dict")
    _check_fits_arch(path, strip_prefixes(state), cfg.arch)


def _check_fits_arch(path: Path, state: dict[str, Any], arch: str | dict[str, Any]) -> None:
    """Parameter names and shapes against ``encoder.arch`` built on the meta device (nothing allocated)."""
    import torch

    from imply.models.config import PRESETS, ViTConfig
    from imply.models.vision_transformer import VisionTransformer

    vit = ViTConfig.from_dict(arch, "encoder.arch") if isinstance(arch, dict) else PRESETS.get(arch)
    if vit is None:
        raise ValueError(f"encoder.arch: {arch!r} is not one of {', '.join(PRESETS)}")
    with torch.device("meta"):
        expected = {k: tuple(v.shape) for k, v in VisionTransformer(vit).state_dict().items()}
    missing = [k for k in expected if k not in state]
    unexpected = [k for k in state if k not in expected]
    wrong = [k for k in expected if k in state and tuple(getattr(state[k], "shape", ())) != expected[k]]
    if missing or unexpected or wrong:
        parts = []
        if missing:
            parts.append(f"{len(missing)} missing (e.g. {missing[0]})")
        if unexpected:
            parts.append(f"{len(unexpected)} unexpected (e.g. {unexpected[0]})")
        if wrong:
            k = wrong[0]
            parts.append(f"{len(wrong)} of another shape (e.g. {k}: {tuple(state[k].shape)} not {expected[k]})")
        raise ValueError(f"encoder.weights: {path} does not fit encoder.arch {arch!r}: parameters {'; '.join(parts)}")


def _check_hf(path: Path) -> None:
    what = "a Hugging Face VJEPA2Model directory; encoder.kind vjepa2_hf"
    if not path.is_dir():
        raise ValueError(f"encoder.weights: {path} is not a directory ({what})")
    config_file = path / "config.json"
    try:
        model_type = json.loads(config_file.read_text()).get("model_type")
    except FileNotFoundError:
        raise ValueError(f"encoder.weights: {path} has no config.json ({what})") from None
    except (OSError, ValueError, AttributeError) as exc:
        raise ValueError(f"encoder.weights: {config_file} is not a JSON model config ({exc})") from None
    if model_type != HF_MODEL_TYPE:
        raise ValueError(f"encoder.weights: {config_file} has model_type {model_type!r}, not {HF_MODEL_TYPE!r}")
    if not any(f for pattern in HF_WEIGHTS_PATTERNS for f in path.glob(pattern)):
        raise ValueError(f"encoder.weights: {path} has no weights file (*.safetensors or *.bin)")
    if importlib.util.find_spec("transformers") is None:
        raise ValueError("encoder.weights: encoder.kind vjepa2_hf needs transformers: pip install 'imply[vjepa2]'")
