"""The object-blind baseline of Section 5: the training set's typical slide at each speed.

A model that cannot tell objects apart can at best predict, for a push at speed v, the
slide typical of the training objects at v. That is what a learned model should beat
once it sees an object's calibration pushes, and what a model trained without them
should match. The typical log slide is a cubic in log speed fit by least squares to the
log slides of the training clips (the geometric mean slide at each speed, as
:func:`imply.study.section4.standins.typical_displacement` is for the table's objects).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

DEGREE = 3


@dataclass(frozen=True)
class TypicalSlide:
    """log d = polynomial in log v (coefficients highest power first, numpy.polyval's order)."""

    coef: np.ndarray

    def log_slide(self, speeds) -> np.ndarray:
        """Typical log slide (log metres) at each speed (m/s); same shape as ``speeds``."""
        return np.polyval(self.coef, np.log(np.asarray(speeds, dtype=float)))

    def slide(self, speeds) -> np.ndarray:
        return np.exp(self.log_slide(speeds))


def fit_typical_slide(speeds, displacements, *, degree: int = DEGREE) -> TypicalSlide:
    """Fit :class:`TypicalSlide` to pushes at ``speeds`` (m/s) that slid ``displacements`` (m, > 0)."""
    v = np.asarray(speeds, dtype=float).ravel()
    d = np.asarray(displacements, dtype=float).ravel()
    if v.shape != d.shape or v.size <= degree:
        raise ValueError(f"the typical slide needs more than {degree} pushes with one displacement each")
    if not (np.all(v > 0) and np.all(d > 0)):
        raise ValueError("speeds and displacements must be positive")
    return TypicalSlide(np.polyfit(np.log(v), np.log(d), degree))


def typical_slide_of_clips(meta: pd.DataFrame) -> TypicalSlide:
    """:func:`fit_typical_slide` on the clips of a training split (``ok`` ones with a positive slide)."""
    ok = meta["displacement"].to_numpy(dtype=float) > 0
    if "ok" in meta.columns:
        ok &= meta["ok"].to_numpy() == 1
    return fit_typical_slide(meta["speed"].to_numpy(dtype=float)[ok], meta["displacement"].to_numpy(dtype=float)[ok])
