"""Synthetic feature splits in the clips stage's formats (clips CSV + features npz), for the model's tests.

The box position at each frame is encoded in the tokens by a fixed random map, so the
tests need neither rendering nor the encoder; the displacement follows a closed-form
law of speed, mass and friction.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

PROFILE = np.array([0.0, 0.15, 0.3, 0.5, 0.65, 0.8, 0.95, 1.0])
TIMES = [0.0, 0.03, 0.06, 0.1, 0.15, 0.25, 0.4]


def synth_split(path: Path, name: str, n_objects: int, heldout: bool, seed: int, grid=(2, 2), dim=8):
    """Write <path>/<name>.csv and <name>.npz like the clips stage's metadata and encoder features."""
    rng = np.random.default_rng(seed)
    mass = np.exp(rng.uniform(np.log(0.2), np.log(2.0), n_objects))
    fric = np.exp(rng.uniform(np.log(0.1), np.log(0.6), n_objects))
    rows = []
    for i in range(n_objects):
        pushes = [("calibration_0", -1, 0.3), ("calibration_1", -1, 0.8)]
        if heldout:
            pushes += [("query", k, v) for k, v in enumerate([0.25, 0.4, 0.55, 0.7, 0.85])]
        else:
            pushes.append(("query", -1, float(rng.uniform(0.15, 1.05))))
        for role, k, v in pushes:
            d = np.exp(2 * np.log(v) - np.log(fric[i]) - 0.5 * np.log(mass[i]) * v - 3.0)
            row = {
                "object_id": f"{name}-{i:05d}",
                "episode": i,
                "role": role,
                "speed_index": k,
                "speed": v,
                "displacement": d,
                "stop_time": 0.5 + d,
                "ok": 1,
                "mass": mass[i],
                "friction": fric[i],
            }
            row.update({f"t{j}": t for j, t in enumerate(TIMES)})
            row["t7"] = 0.5 + d
            rows.append(row)
    meta = pd.DataFrame(rows)
    meta.insert(0, "clip_id", np.arange(len(meta)))
    p = grid[0] * grid[1]
    w = np.random.default_rng(99).normal(size=(p, dim))
    pos = meta["displacement"].to_numpy()[:, None] * PROFILE[None, :] * 10.0  # (n, 8)
    tokens = np.sin(pos[:, :, None, None] * w[None, None] + np.arange(dim)[None, None, None, :] * 0.3)
    tokens += 0.01 * rng.normal(size=tokens.shape)
    meta.to_csv(path / f"{name}.csv", index=False)
    np.savez(
        path / f"{name}.npz", tokens=tokens.astype(np.float16), clip_id=meta["clip_id"].to_numpy(), grid=np.array(grid)
    )
    return path / f"{name}.npz", path / f"{name}.csv"
