"""The chi-square and Student t tails the diagnostic's tests read, from :mod:`scipy.special`.

The same formulas :mod:`scipy.stats` evaluates for these distributions (so the same numbers), without importing
:mod:`scipy.stats`, whose import is about a third of the diagnostic package's and would be paid by every ``imply
diagnose`` and every workflow job that diagnoses. Arguments outside the distributions' domains give NaN,
as :mod:`scipy.stats` does.
"""

from __future__ import annotations

import numpy as np
from scipy import special


def chi2_ppf(q: float, df: float) -> float:
    """The chi-square quantile at probability ``q`` with ``df`` degrees of freedom."""
    if not (df > 0 and 0 <= q <= 1):
        return float("nan")
    return float(2.0 * special.gammaincinv(df / 2.0, q))


def chi2_sf(x: float, df: float) -> float:
    """The chi-square survival function (upper tail) at ``x`` with ``df`` degrees of freedom."""
    if not df > 0 or np.isnan(x):
        return float("nan")
    return float(special.chdtrc(df, max(x, 0.0)))


def t_ppf(q: float, df: float) -> float:
    """Student's t quantile at probability ``q`` with ``df`` degrees of freedom."""
    if not (df > 0 and 0 <= q <= 1):
        return float("nan")
    if q == 0:  # the lower end (special's inverse answers +inf there)
        return float("-inf")
    return float(special.stdtrit(df, q))
