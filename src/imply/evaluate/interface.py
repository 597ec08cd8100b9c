"""What a world model is asked, what it must return, and the checks on what it returns.

A model is any object with

* ``kind``: ``"frames"``, ``"latents"`` or ``"displacements"`` (:data:`KINDS`);
* ``rollout(request: RolloutRequest) -> numpy array``: the futures of a batch of sample
  sets, one per object of the request, each with the K query pushes (see
  :data:`OUTPUT_SHAPES`);
* for ``latents`` only, ``encode(frames) -> numpy array``: its own encoding of real frames,
  uint8 (N, H, W, 3) -> float (N, ...), the same per-frame shape its rollouts end in;

and optionally ``name`` (the report's label), ``batch_size`` (objects per call) and
``stochastic`` (True: it is asked for several sample sets per object). A factory
``MODULE:FUNCTION`` named on the command line builds it; the factory may take the suite as
keyword ``suite`` (to read the camera, say), and ``MODULE:FUNCTION,KEY=VALUE,...`` passes
string options (a checkpoint path, say).

One request holds one condition and one sample index for a batch of objects, and all K
query speeds of each: a model can keep one hypothesis of an object across the K pushes
of a set (one latent drawn per set, say), and sample index s of one object is always the
same request, so a seeded model gives the same futures on a rerun.
"""

from __future__ import annotations

import importlib
import inspect
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np

KINDS: tuple[str, ...] = ("frames", "latents", "displacements")
OUTPUT_SHAPES = {
    "frames": "uint8 (B, K, F, H, W, 3): F >= 1 generated frames after the context; the last is read as the rest frame",
    "latents": "float (B, K, *S): the predicted rest-frame encoding, S = the shape encode() gives one frame",
    "displacements": "float (B, K): the slide of each push, metres (>= 0)",
}
DEFAULT_BATCH = 64


class ModelError(ValueError):
    """A model that cannot be loaded, or whose output breaks the interface (the message names where)."""


@dataclass(frozen=True, eq=False)
class RolloutRequest:
    """B sample sets to roll out: B objects, each pushed at the K query speeds, in one condition.

    object_ids: (B,) str. condition: ``own`` (the object's own calibration pushes are
    shown), ``other`` (another object's), or ``none`` (no calibration). sample: the sample
    set's index (0 for a deterministic model; a stochastic model should draw sample set s
    of an object the same way each time it is asked).
    query_speeds: (K,) commanded pusher speed of each query push, m/s.
    context_frames: uint8 (B, K, C, H, W, 3), the first C frames of each query push.
    calibration_speeds: (2,) m/s, or None in condition ``none``.
    calibration_frames: uint8 (B, 2, T, H, W, 3) calibration clips (the last frame at
      rest), or None. calibration_displacement: (B, 2) their observed slides, metres, or None.
    frame_times: (T - 1,) nominal times of the clip frames, s (the T-th is at rest).
    metres_per_pixel: the camera's scale.
    """

    object_ids: tuple[str, ...]
    condition: str
    sample: int
    query_speeds: np.ndarray
    context_frames: np.ndarray
    calibration_speeds: np.ndarray | None
    calibration_frames: np.ndarray | None
    calibration_displacement: np.ndarray | None
    frame_times: np.ndarray
    metres_per_pixel: float

    def __len__(self) -> int:
        return len(self.object_ids)


@runtime_checkable
class WorldModel(Protocol):
    """The interface :func:`imply.evaluate.evaluate` calls (``encode`` for latent models only)."""

    kind: str

    def rollout(self, request: RolloutRequest) -> np.ndarray: ...


def parse_model_spec(spec: str) -> tuple[str, str, dict[str, str]]:
    """``MODULE:FACTORY[,KEY=VALUE...]`` -> (module, factory, keyword arguments as strings)."""
    target, *pairs = spec.split(",")
    module_name, sep, attr = target.partition(":")
    if not sep or not module_name or not attr:
        raise ModelError(f"--model {spec!r}: expected MODULE:FACTORY[,KEY=VALUE...], e.g. my_model:build")
    kwargs: dict[str, str] = {}
    for pair in pairs:
        key, eq, value = pair.partition("=")
        if not eq or not key.strip().isidentifier():
            raise ModelError(f"--model {spec!r}: {pair!r} is not KEY=VALUE")
        if key.strip() in kwargs or key.strip() == "suite":
            raise ModelError(f"--model {spec!r}: {key.strip()!r} given twice (or reserved: suite)")
        kwargs[key.strip()] = value
    return module_name, attr, kwargs


def load_model(spec: str, *, suite: Any = None) -> Any:
    """Build the model named ``MODULE:FACTORY[,KEY=VALUE...]`` (module importable, or a path to a .py file).

    Each ``KEY=VALUE`` is passed to the factory as a keyword argument (a string), e.g.
    ``imply.models.world_model:trained_predictor,checkpoint=model.pt,encoder=encoder.pt``.
    """
    module_name, attr, kwargs = parse_model_spec(spec)
    try:
        if module_name.endswith(".py"):
            module = _module_from_file(module_name)
        else:
            module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ModelError(f"--model {spec!r}: cannot import {module_name!r}: {exc}") from exc
    factory = getattr(module, attr, None)
    if not callable(factory):
        raise ModelError(f"--model {spec!r}: {module_name} has no callable {attr!r}")
    params = inspect.signature(factory).parameters
    takes_any = any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values())
    unknown = [k for k in kwargs if k not in params and not takes_any]
    if unknown:
        raise ModelError(f"--model {spec!r}: {attr} takes no option {', '.join(map(repr, unknown))}")
    if "suite" in params:
        kwargs = {**kwargs, "suite": suite}
    try:
        model = factory(**kwargs)
    except (OSError, ValueError, TypeError) as exc:
        raise ModelError(f"--model {spec!r}: {exc}") from exc
    check_model(model, spec)
    return model


def _module_from_file(path: str):
    import importlib.util
    from pathlib import Path

    file = Path(path)
    if not file.is_file():
        raise ImportError(f"no file {path}")
    spec = importlib.util.spec_from_file_location(file.stem, file)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def check_model(model: Any, label: str) -> None:
    """The attributes the harness needs, with one message naming what is missing."""
    kind = getattr(model, "kind", None)
    if kind not in KINDS:
        raise ModelError(f"model {label}: kind must be one of {', '.join(KINDS)}, not {kind!r}")
    if not callable(getattr(model, "rollout", None)):
        raise ModelError(f"model {label}: has no rollout(request) method")
    if kind == "latents" and not callable(getattr(model, "encode", None)):
        raise ModelError(f"model {label}: a latents model needs encode(frames) for its readout")
    batch = getattr(model, "batch_size", DEFAULT_BATCH)
    if not isinstance(batch, int | np.integer) or batch < 1:
        raise ModelError(f"model {label}: batch_size must be a positive integer, not {batch!r}")


def model_name(model: Any, fallback: str) -> str:
    return str(getattr(model, "name", None) or fallback)


def where(request: RolloutRequest, b: int | None = None, k: int | None = None) -> str:
    """'object O, condition C, speed V m/s, sample S' for an error message."""
    obj = request.object_ids[b] if b is not None else f"{request.object_ids[0]}..{request.object_ids[-1]}"
    speed = f", speed {request.query_speeds[k]:g} m/s" if k is not None else ""
    return f"object {obj}, condition {request.condition}{speed}, sample {request.sample}"


def check_output(
    out: Any, *, kind: str, request: RolloutRequest, frame_shape: tuple[int, ...], token_shape: tuple[int, ...] | None
) -> np.ndarray:
    """``out`` as an array of the kind's shape and dtype, or :class:`ModelError` naming the first bad value.

    frame_shape: (H, W, 3) of the suite. token_shape: the per-frame shape of the model's
    ``encode`` (latents only).
    """
    b, k = len(request), len(request.query_speeds)
    try:
        arr = np.asarray(out)
    except Exception as exc:  # a model may return anything
        raise ModelError(f"{where(request)}: rollout returned {type(out).__name__}, not an array ({exc})") from exc
    if kind == "frames":
        if arr.dtype != np.uint8:
            raise ModelError(f"{where(request)}: frames must be uint8, got {arr.dtype}")
        ok = arr.ndim == 6 and arr.shape[:2] == (b, k) and arr.shape[2] >= 1 and arr.shape[3:] == tuple(frame_shape)
        expected = f"({b}, {k}, F, {', '.join(map(str, frame_shape))})"
    elif kind == "latents":
        ok = arr.ndim >= 2 and arr.shape[:2] == (b, k) and (token_shape is None or arr.shape[2:] == token_shape)
        expected = f"({b}, {k}, {', '.join(map(str, token_shape or ('...',)))})"
    else:
        ok = arr.shape == (b, k)
        expected = f"({b}, {k})"
    if not ok:
        raise ModelError(f"{where(request)}: {kind} of shape {tuple(arr.shape)}, expected {expected}")
    if kind != "frames":
        if not np.issubdtype(arr.dtype, np.number) or np.issubdtype(arr.dtype, np.complexfloating):
            raise ModelError(f"{where(request)}: {kind} must be real numbers, got {arr.dtype}")
        arr = arr.astype(np.float64 if kind == "displacements" else np.float32, copy=False)
        finite = np.isfinite(arr.reshape(b, k, -1)).all(axis=2)
        if not finite.all():
            bi, ki = (int(i) for i in np.argwhere(~finite)[0])
            raise ModelError(f"{where(request, bi, ki)}: {kind} contain NaN or infinite values")
        if kind == "displacements" and (arr < 0).any():
            bi, ki = (int(i) for i in np.argwhere(arr < 0)[0])
            raise ModelError(f"{where(request, bi, ki)}: negative displacement {arr[bi, ki]:g} m")
    return arr
