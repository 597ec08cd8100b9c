"""The pixel model's scoring: per-object slopes read off per_object.csv, and the targets' claims."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from imply.paper.registry import load_registry
from imply.study.pixel_model import per_object_slopes, pixel_claims

GOOD = {
    "pxCalSlopeRatio": 1.05,
    "pxNoCalSlopeRatio": 0.9,
    "pxCalSaliency": 1.02,
    "pxNoCalSaliency": 0.95,
    "pxCalPsnr": 40.0,
    "pxNoCalPsnr": 35.0,
    "pxCalTrackOwn": 0.95,
    "pxCalTrackOther": 0.0,
    "pxCalAnchOwn": 0.9,
    "pxNoCalSpread": 0.4,
    "pxCalSpread": 0.01,
    "pxSelAnchTrack": 0.95,
    "pxSelAnchCut": 0.8,
    "pxSelAnchOverOracle": 0.05,
    "pxSelSelfTrack": 0.05,
    "pxSelRandomTrack": 0.0,
}


def test_per_object_slopes_are_read_per_object_and_per_condition():
    speeds = np.array([0.25, 0.4, 0.55, 0.7, 0.85])
    rows = []
    for obj, (slope, scale) in {"a": (1.0, 0.1), "b": (2.0, 0.05)}.items():
        for cond, factor in (("own", 1.0), ("other", 0.0)):
            for v in speeds:
                read = scale * v ** (slope * factor)  # condition other: the same slide at every speed
                rows.append(
                    {
                        "condition": cond,
                        "sample": 0,
                        "object_id": obj,
                        "speed_m_s": v,
                        "read_displacement_m": read,
                        "true_displacement_m": scale * v**slope,
                    }
                )
    df = pd.DataFrame(rows).sample(frac=1.0, random_state=0)  # order must not matter
    read, true = per_object_slopes(df, condition="own")
    assert np.allclose(read, [1.0, 2.0]) and np.allclose(true, [1.0, 2.0])
    read, _ = per_object_slopes(df, condition="other")
    assert np.allclose(read, 0.0)
    with pytest.raises(ValueError, match="condition 'none'"):
        per_object_slopes(df, condition="none")


def _claims(**changes):
    registry = load_registry()
    return {c.id: c for c in pixel_claims(registry.values({**GOOD, **changes}))}


def test_claims_hold_on_the_targets_and_fail_past_each():
    assert all(c.holds for c in _claims().values())
    assert not _claims(pxNoCalSlopeRatio=0.8)["px-moves-with-the-action"].holds
    assert not _claims(pxCalSaliency=1.12)["px-frames-readable"].holds
    assert not _claims(pxCalTrackOther=0.4)["px-calibrated-tracks-its-object"].holds
    assert not _claims(pxCalSpread=0.25)["px-uncertain-without-calibration"].holds
    # choosing by self-disagreement must stay near chance for the anchored claim to hold
    assert not _claims(pxSelSelfTrack=0.5)["px-anchored-chooses-among-samples"].holds
    assert not _claims(pxSelAnchOverOracle=0.3)["px-anchored-chooses-among-samples"].holds
