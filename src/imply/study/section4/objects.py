"""The objects of the controlled validation and their true pushes.

:func:`draw_objects` -> ``objects.csv``: ``objects.n`` evaluation and ``objects.n_train``
training objects (population ``eval``/``train``); :func:`simulate_truth` -> ``truth.csv``:
every evaluation object pushed at the calibration and the K query speeds, every training
object at the query speeds, with its true physics and geometry, in one batched
simulation. :func:`truth_arrays` reads the long table back as arrays.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from imply.sim import SceneConfig, simulate_pushes
from imply.study.section4.config import ObjectsConfig
from imply.table import PushTable

# one random stream per step of Section 4, so changing one step's settings leaves the
# others' draws alone
STREAM_OBJECTS, STREAM_JITTER, STREAM_NOISE, STREAM_SELECTION = 1, 2, 3, 4


def rng_for(seed: int, stream: int) -> np.random.Generator:
    """The random generator of one step (``stream``) of the study seeded by ``seed``."""
    return np.random.default_rng([int(seed), int(stream)])


def draw_objects(
    settings: ObjectsConfig, *, scene: SceneConfig, seed: int, table: PushTable | None = None
) -> pd.DataFrame:
    """Evaluation and training objects: object_id, population, mass, friction, size_x/y/z."""
    mass, fric = settings.mass, settings.friction
    if table is not None:
        try:
            table.check_range(masses=[mass.min, mass.max], frictions=[fric.min, fric.max])
        except ValueError as exc:
            raise ValueError(f"section4.objects: {exc}") from exc
    rng = rng_for(seed, STREAM_OBJECTS)
    frames = []
    for population, n in (("eval", settings.n), ("train", settings.n_train)):
        u = rng.random((n, 2))
        z = rng.standard_normal((n, 3))
        m = np.exp(np.log(mass.min) + u[:, 0] * np.log(mass.max / mass.min))
        mu = np.exp(np.log(fric.min) + u[:, 1] * np.log(fric.max / fric.min))
        size = np.asarray(scene.box_half_extents)[None, :] * np.exp(settings.size_log_sd * z)
        frames.append(
            pd.DataFrame(
                {
                    "object_id": [f"{population}{i:04d}" for i in range(n)],
                    "population": population,
                    "mass": m,
                    "friction": mu,
                    "size_x": size[:, 0],
                    "size_y": size[:, 1],
                    "size_z": size[:, 2],
                }
            )
        )
    return pd.concat(frames, ignore_index=True)


def simulate_grid(
    speeds,
    masses,
    frictions,
    half_extents,
    *,
    scene: SceneConfig | None = None,
    nthread: int = 0,
    progress: bool = False,
) -> tuple[np.ndarray, np.ndarray]:
    """Push every object at every speed in one batched simulation.

    Args:
      speeds: (K,) speeds shared by all objects, or (N, K) per object.
      masses, frictions: (N,) or (N, K) -- per object, or per (object, speed).
      half_extents: (N, 3) box half-extents per object.
    Returns:
      displacement (N, K) in metres and ok (N, K), the simulator's own checks.
    """
    masses = np.asarray(masses, dtype=float)
    n = masses.shape[0]
    speeds = np.asarray(speeds, dtype=float)
    k = speeds.shape[-1]
    v = np.broadcast_to(speeds, (n, k))
    m = np.broadcast_to(masses.reshape(n, -1), (n, k))
    mu = np.broadcast_to(np.asarray(frictions, dtype=float).reshape(n, -1), (n, k))
    he = np.broadcast_to(np.asarray(half_extents, dtype=float)[:, None, :], (n, k, 3))
    res = simulate_pushes(
        v.ravel(), m.ravel(), mu.ravel(), he.reshape(-1, 3), scene=scene, nthread=nthread, progress=progress
    )
    return res.displacement.reshape(n, k), res.ok.reshape(n, k)


def population(objects: pd.DataFrame, name: str) -> pd.DataFrame:
    """The objects of one population (``eval`` or ``train``), in file order."""
    return objects[objects["population"] == name].reset_index(drop=True)


def sizes(objects: pd.DataFrame) -> np.ndarray:
    """(N, 3) box half-extents of the objects."""
    return objects[["size_x", "size_y", "size_z"]].to_numpy(float)


def simulate_truth(
    objects: pd.DataFrame,
    *,
    query_speeds,
    calibration_speeds,
    scene: SceneConfig,
    nthread: int = 0,
    progress: bool = False,
) -> pd.DataFrame:
    """True pushes, long format: object_id, population, role (calibration|query), speed, displacement, ok.

    One batch: evaluation objects at calibration + query speeds, training objects at
    query speeds (padded to the same speed list and dropped after, so a single call).
    """
    q = np.asarray(query_speeds, dtype=float)
    c = np.asarray(calibration_speeds, dtype=float)
    speeds = np.concatenate([c, q])
    roles = ["calibration"] * c.size + ["query"] * q.size
    both = pd.concat([population(objects, "eval"), population(objects, "train")], ignore_index=True)
    # training objects only need the query speeds; simulating them at the same list and
    # dropping their calibration pushes buys a single batched call for a few hundred pushes
    disp, ok = simulate_grid(
        speeds,
        both["mass"].to_numpy(float),
        both["friction"].to_numpy(float),
        sizes(both),
        scene=scene,
        nthread=nthread,
        progress=progress,
    )
    n = len(both)
    frame = pd.DataFrame(
        {
            "object_id": np.repeat(both["object_id"].to_numpy(), speeds.size),
            "population": np.repeat(both["population"].to_numpy(), speeds.size),
            "role": np.tile(roles, n),
            "speed": np.tile(speeds, n),
            "displacement": disp.ravel(),
            "ok": ok.ravel(),
        }
    )
    keep = (frame["population"] == "eval") | (frame["role"] == "query")
    return frame[keep].reset_index(drop=True)


def truth_arrays(truth: pd.DataFrame, *, query_speeds, calibration_speeds) -> dict[str, Any]:
    """Truth as arrays: ids, calib (N, C), query (N, K), train (M, K), in file order, and the speeds."""
    q = np.asarray(query_speeds, dtype=float)
    c = np.asarray(calibration_speeds, dtype=float)
    out: dict[str, Any] = {"query_speeds": q, "calib_speeds": c}
    ev = truth[truth["population"] == "eval"]
    ids = list(dict.fromkeys(ev["object_id"]))
    out["ids"] = ids
    out["calib"] = pivot(ev[ev["role"] == "calibration"], ids, c, "truth calibration")
    out["query"] = pivot(ev[ev["role"] == "query"], ids, q, "truth query")
    tr = truth[truth["population"] == "train"]
    out["train"] = pivot(tr, list(dict.fromkeys(tr["object_id"])), q, "truth training")
    return out


def pivot(frame: pd.DataFrame, ids: list[str], speeds: np.ndarray, what: str) -> np.ndarray:
    """(len(ids), len(speeds)) displacements from a long frame; every cell must be present once."""
    table = frame.pivot_table(index="object_id", columns="speed", values="displacement", aggfunc="first")
    missing_speeds = [v for v in speeds if not np.any(np.isclose(table.columns.to_numpy(float), v))]
    if missing_speeds or len(frame) != len(ids) * speeds.size:
        raise ValueError(f"{what}: expected {len(ids)} objects x speeds {list(speeds)}, got {len(frame)} rows")
    cols = [table.columns[np.argmin(np.abs(table.columns.to_numpy(float) - v))] for v in speeds]
    return table.loc[ids, cols].to_numpy(float)
