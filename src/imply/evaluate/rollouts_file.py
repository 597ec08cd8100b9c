"""Rollouts generated elsewhere (on a GPU cluster, say), stored for ``imply evaluate --rollouts``.

Layout (``.npz``; write it with :func:`write_rollouts_file`), R rows, one per rollout::

    format       "imply-rollouts"            version   1
    kind         "frames" | "latents" | "displacements"
    model        the model's name, as the report shows it
    suite        (optional) the suite's checksum (manifest files["suite.npz"]); checked if present
    object_id    str (R,)    an object of the suite
    condition    str (R,)    own | other | none
    speed        float (R,)  one of the suite's query speeds, m/s
    sample       int (R,)    sample set index, 0 .. S-1
    output       frames uint8 (R, F, H, W, 3) | latents float (R, *S) | displacements float (R,) metres
    encoded_train, encoded_check   latents only: the model's encode() of the suite's
                 train_frames[:, -1] and check_frames[:, -1] (its readout is fitted on them)

Every (object, condition, speed, sample) of the conditions evaluated must be present once,
for samples 0 .. S-1. Displacements may also come as a CSV with columns
``object_id,condition,speed,sample,displacement`` (the model's name is the file's stem).
Anything missing, repeated or unknown is one error naming the row, or the object,
condition, speed and sample that is missing.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from imply.evaluate.interface import KINDS
from imply.evaluate.suite import Suite
from imply.io import write_npz

ROLLOUTS_FORMAT = "imply-rollouts"
ROLLOUTS_VERSION = 1
CSV_COLUMNS = ("object_id", "condition", "speed", "sample", "displacement")


class RolloutsFileError(ValueError):
    """A rollouts file that does not match the suite or the layout (the message names the row or key)."""


@dataclass(frozen=True, eq=False)
class RolloutsFile:
    """A checked rollouts file: ``row[c, s, n, k]`` is the row of condition c, sample s, object n, speed k."""

    model: str
    kind: str
    conditions: tuple[str, ...]
    n_samples: int
    row: np.ndarray
    output: np.ndarray
    encoded_train: np.ndarray | None
    encoded_check: np.ndarray | None
    encoding: dict | None = None  # videos read from files: codec, height, width, fps, bit_rate (lossy ones only)

    def batch(self, condition: str, sample: int, index: np.ndarray) -> np.ndarray:
        """(B, K, ...) outputs of objects ``index`` in ``condition``, sample set ``sample``."""
        return self.output[self.row[self.conditions.index(condition), sample][index]]


def write_rollouts_file(
    path: str | Path,
    *,
    kind: str,
    model: str,
    object_id: Sequence[str],
    condition: Sequence[str],
    speed: Sequence[float],
    sample: Sequence[int],
    output: np.ndarray,
    suite: str | None = None,
    encoded_train: np.ndarray | None = None,
    encoded_check: np.ndarray | None = None,
) -> None:
    """Write rollouts in the layout above (atomically)."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}")
    arrays = {
        "format": np.asarray(ROLLOUTS_FORMAT),
        "version": np.int64(ROLLOUTS_VERSION),
        "kind": np.asarray(kind),
        "model": np.asarray(model),
        "object_id": np.asarray(object_id, dtype=str),
        "condition": np.asarray(condition, dtype=str),
        "speed": np.asarray(speed, dtype=float),
        "sample": np.asarray(sample, dtype=np.int64),
        "output": np.asarray(output),
    }
    if suite is not None:
        arrays["suite"] = np.asarray(suite)
    if kind == "latents":
        if encoded_train is None or encoded_check is None:
            raise ValueError("a latents rollouts file needs encoded_train and encoded_check")
        arrays["encoded_train"] = np.asarray(encoded_train)
        arrays["encoded_check"] = np.asarray(encoded_check)
    write_npz(path, compressed=True, **arrays)


def _fail(path: Path, message: str) -> RolloutsFileError:
    return RolloutsFileError(f"{path}: {message}")


def _load_npz(path: Path) -> dict[str, np.ndarray]:
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {name: z[name] for name in z.files}
    except (OSError, ValueError) as exc:
        raise _fail(path, f"not a readable .npz ({exc})") from exc
    if str(data.get("format", "")) != ROLLOUTS_FORMAT:
        raise _fail(path, f"not a rollouts file (no format {ROLLOUTS_FORMAT!r}; see imply.evaluate.rollouts_file)")
    if int(data.get("version", -1)) != ROLLOUTS_VERSION:
        raise _fail(path, f"rollouts version {data.get('version')}; this imply reads version {ROLLOUTS_VERSION}")
    for key in ("kind", "model", "object_id", "condition", "speed", "sample", "output"):
        if key not in data:
            raise _fail(path, f"has no {key!r} array")
    return data


def _load_csv(path: Path) -> dict[str, np.ndarray]:
    try:
        frame = pd.read_csv(path, dtype={"object_id": str, "condition": str})
    except (OSError, ValueError) as exc:
        raise _fail(path, f"not a readable CSV ({exc})") from exc
    missing = [c for c in CSV_COLUMNS if c not in frame.columns]
    if missing:
        raise _fail(path, f"no column {missing[0]!r} (columns: {', '.join(CSV_COLUMNS)})")
    for col in ("speed", "sample", "displacement"):
        values = pd.to_numeric(frame[col], errors="coerce")
        bad = values.isna() & frame[col].notna() | frame[col].isna()
        if bad.any():
            i = int(np.flatnonzero(bad.to_numpy())[0])
            raise _fail(path, f"row {i + 2}, column {col}: {frame[col].iloc[i]!r} is not a number")
        frame[col] = values
    if not (frame["sample"] == frame["sample"].round()).all():
        i = int(np.flatnonzero((frame["sample"] != frame["sample"].round()).to_numpy())[0])
        raise _fail(path, f"row {i + 2}, column sample: {frame['sample'].iloc[i]!r} is not an integer")
    return {
        "kind": np.asarray("displacements"),
        "model": np.asarray(path.stem),
        "object_id": frame["object_id"].to_numpy(dtype=str),
        "condition": frame["condition"].to_numpy(dtype=str),
        "speed": frame["speed"].to_numpy(dtype=float),
        "sample": frame["sample"].to_numpy(dtype=np.int64),
        "output": frame["displacement"].to_numpy(dtype=float),
    }


def read_rollouts_file(path: str | Path, *, suite: Suite, conditions: Sequence[str]) -> RolloutsFile:
    """Read and check a rollouts file against ``suite`` for ``conditions`` (see the module docstring)."""
    path = Path(path)
    if not path.is_file():
        raise _fail(path, "no such file")
    data = _load_csv(path) if path.suffix.lower() == ".csv" else _load_npz(path)
    csv = path.suffix.lower() == ".csv"
    line = (lambda i: f"row {i + 2}") if csv else (lambda i: f"row {i}")
    kind = str(data["kind"])
    if kind not in KINDS:
        raise _fail(path, f"kind {kind!r} is not one of {', '.join(KINDS)}")
    if "suite" in data and str(data["suite"]) != suite.checksum:
        raise _fail(path, f"made for suite {str(data['suite'])[:12]}, not this one ({suite.checksum[:12]})")
    obj = np.asarray(data["object_id"]).astype(str)
    cond = np.asarray(data["condition"]).astype(str)
    speed = np.asarray(data["speed"], dtype=float)
    sample = np.asarray(data["sample"])
    output = np.asarray(data["output"])
    r = len(obj)
    for name, arr in (("condition", cond), ("speed", speed), ("sample", sample), ("output", output)):
        if len(arr) != r:
            raise _fail(path, f"{name} has {len(arr)} rows, object_id {r}")
    if not np.issubdtype(sample.dtype, np.integer):
        raise _fail(path, f"sample must be integers, not {sample.dtype}")

    object_index = {o: i for i, o in enumerate(suite.object_ids.astype(str))}
    n_idx = np.array([object_index.get(o, -1) for o in obj], dtype=np.int64)
    if (n_idx < 0).any():
        i = int(np.flatnonzero(n_idx < 0)[0])
        raise _fail(path, f"{line(i)}: object {str(obj[i])!r} is not in the suite")
    k_idx = np.full(r, -1, dtype=np.int64)
    for k, v in enumerate(suite.query_speeds):
        k_idx[np.isclose(speed, v, rtol=0, atol=1e-9)] = k
    if (k_idx < 0).any():
        i = int(np.flatnonzero(k_idx < 0)[0])
        speeds = ", ".join(f"{v:g}" for v in suite.query_speeds)
        raise _fail(path, f"{line(i)}: speed {speed[i]:g} is not one of the suite's query speeds ({speeds})")
    if (sample < 0).any():
        i = int(np.flatnonzero(sample < 0)[0])
        raise _fail(path, f"{line(i)}: sample {sample[i]} is negative")
    keep = np.isin(cond, list(conditions))
    unknown = ~np.isin(cond, ["own", "other", "none"])
    if unknown.any():
        i = int(np.flatnonzero(unknown)[0])
        raise _fail(path, f"{line(i)}: condition {str(cond[i])!r} is not own, other or none")
    n_samples = int(sample[keep].max()) + 1 if keep.any() else 1
    shape = (len(conditions), n_samples, suite.n_objects, suite.n_speeds)
    c_idx = np.array([list(conditions).index(c) if c in conditions else -1 for c in cond], dtype=np.int64)
    rows = np.flatnonzero(keep)
    flat = np.ravel_multi_index((c_idx[rows], sample[rows], n_idx[rows], k_idx[rows]), shape)
    count = np.bincount(flat, minlength=int(np.prod(shape)))
    if (count > 1).any():
        dup = int(np.flatnonzero(count > 1)[0])
        i = int(rows[np.flatnonzero(flat == dup)[1]])
        raise _fail(
            path,
            f"{line(i)}: a second rollout of object {obj[i]}, condition {cond[i]}, "
            f"speed {speed[i]:g} m/s, sample {sample[i]}",
        )
    if (count == 0).any():
        c, s, n, k = np.unravel_index(int(np.flatnonzero(count == 0)[0]), shape)
        raise _fail(
            path,
            f"no rollout of object {suite.object_ids[n]}, condition {conditions[c]}, speed "
            f"{suite.query_speeds[k]:g} m/s, sample {s} (give --conditions to evaluate fewer)",
        )
    row = np.empty(int(np.prod(shape)), dtype=np.int64)
    row[flat] = rows
    enc_train = enc_check = None
    if kind == "latents":
        if "encoded_train" not in data or "encoded_check" not in data:
            raise _fail(
                path,
                "a latents file needs encoded_train and encoded_check (its encode() of the suite's "
                "train_frames[:, -1] and check_frames[:, -1])",
            )
        enc_train, enc_check = np.asarray(data["encoded_train"]), np.asarray(data["encoded_check"])
        for name, arr, n in (
            ("encoded_train", enc_train, len(suite.train_frames)),
            ("encoded_check", enc_check, len(suite.check_frames)),
        ):
            if arr.ndim < 2 or len(arr) != n:
                raise _fail(path, f"{name} has shape {arr.shape}, expected ({n}, ...)")
            if not np.issubdtype(arr.dtype, np.number) or not np.isfinite(arr).all():
                raise _fail(path, f"{name} must be finite numbers")
    if kind == "displacements" and output.ndim != 1:
        raise _fail(path, f"displacements output must be (R,), not {output.shape}")
    return RolloutsFile(
        model=str(data["model"]),
        kind=kind,
        conditions=tuple(conditions),
        n_samples=n_samples,
        row=row.reshape(shape),
        output=output,
        encoded_train=enc_train,
        encoded_check=enc_check,
    )
