"""The diagnostic's chi-square and t tails give scipy.stats's numbers, and a diagnosis never imports scipy.stats."""

import subprocess
import sys

import numpy as np
import pytest
from scipy import stats

from imply.diagnose.tails import chi2_ppf, chi2_sf, t_ppf


@pytest.mark.parametrize("df", [0.5, 1, 2, 3, 7, 40.5, 300])
def test_the_tails_are_scipy_stats_own(df):
    qs = np.r_[0.0, np.linspace(0.001, 0.999, 41), 0.975, 1.0]
    xs = np.r_[0.0, np.geomspace(1e-3, 1e3, 41) * df, np.inf]
    assert [chi2_ppf(q, df) for q in qs] == [float(stats.chi2.ppf(q, df)) for q in qs]
    assert [chi2_sf(x, df) for x in xs] == [float(stats.chi2.sf(x, df)) for x in xs]
    assert [t_ppf(q, df) for q in qs] == [float(stats.t.ppf(q, df)) for q in qs]


def test_outside_the_domain_is_nan_as_in_scipy_stats():
    for value, theirs in (
        (chi2_ppf(0.5, 0), stats.chi2.ppf(0.5, 0)),
        (chi2_ppf(1.5, 2), stats.chi2.ppf(1.5, 2)),
        (chi2_sf(1.0, -1), stats.chi2.sf(1.0, -1)),
        (chi2_sf(float("nan"), 2), stats.chi2.sf(float("nan"), 2)),
        (t_ppf(0.5, 0), stats.t.ppf(0.5, 0)),
    ):
        assert np.isnan(value) and np.isnan(theirs)
    assert chi2_sf(-1.0, 3) == stats.chi2.sf(-1.0, 3) == 1.0


def test_a_diagnosis_does_not_import_scipy_stats():
    code = "import sys, imply.diagnose.run; print('scipy.stats' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"
