"""The gap benchmark's rates judged on counts."""

import pandas as pd

from imply.diagnose.benchmark import wrong_share


def test_two_false_alarms_in_forty_meet_a_five_percent_target():
    correct = pd.Series([True] * 38 + [False] * 2)
    assert 1.0 - correct.mean() > 0.05  # the rounding the count avoids
    assert wrong_share(correct) <= 0.05
    assert wrong_share(correct) == 0.05


def test_wrong_share_counts_wrong_verdicts_and_is_nan_without_logs():
    assert wrong_share(pd.Series([True, False, False, True])) == 0.5
    assert wrong_share(pd.Series([1, 1, 0])) == 1 / 3
    assert pd.isna(wrong_share(pd.Series([], dtype=bool)))
