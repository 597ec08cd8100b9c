"""Section 5 rollout tables built in closed form, for the tests of its scoring."""

from __future__ import annotations

import numpy as np
import pandas as pd

QUERY = np.array([0.3, 0.5, 0.7, 0.9])
CALIB = np.array([0.4, 0.8])


def rollout_table(true_mu: np.ndarray, contexts: dict[str, np.ndarray]) -> pd.DataFrame:
    """A rollout table: per context, predictions from that context's friction per object."""

    def slide(v, mu):
        return 0.05 * v**2 / mu

    rows = []
    for ctx, pred_mu in contexts.items():
        for i, (mu, pmu) in enumerate(zip(true_mu, pred_mu, strict=True)):
            oid = f"o{i:03d}"
            for k, v in enumerate(QUERY):
                rows.append(
                    dict(
                        object_id=oid,
                        context=ctx,
                        role="rollout",
                        speed_index=k,
                        speed=v,
                        displacement=slide(v, pmu),
                        true_displacement=slide(v, mu),
                    )
                )
            for k, v in enumerate(CALIB):
                rows.append(
                    dict(
                        object_id=oid,
                        context=ctx,
                        role="calibration",
                        speed_index=k,
                        speed=v,
                        displacement=slide(v, mu),
                        true_displacement=slide(v, mu),
                    )
                )
    return pd.DataFrame(rows)
