"""The gap benchmark's rates judged on counts, and what a verdict told the cause would state."""

from types import SimpleNamespace

import pandas as pd

from imply.realworld.benchmark import told_error, wrong_share


def test_two_false_alarms_in_forty_meet_a_five_percent_target():
    correct = pd.Series([True] * 38 + [False] * 2)
    assert 1.0 - correct.mean() > 0.05  # the rounding the count avoids
    assert wrong_share(correct) <= 0.05
    assert wrong_share(correct) == 0.05


def test_wrong_share_counts_wrong_verdicts_and_is_nan_without_logs():
    assert wrong_share(pd.Series([True, False, False, True])) == 0.5
    assert wrong_share(pd.Series([1, 1, 0])) == 1 / 3
    assert pd.isna(wrong_share(pd.Series([], dtype=bool)))


def _hyp(effects, weight, magnitude, discrepancy=False):
    est = SimpleNamespace(magnitude=magnitude, components={effects[0]: magnitude} if effects else {})
    return SimpleNamespace(effects=effects, weight=weight, discrepancy=discrepancy, estimates=[est] if effects else [])


def test_told_error_reads_the_heavier_of_the_true_effects_own_hypotheses_whatever_leads():
    summary = SimpleNamespace(
        hypotheses=[
            _hyp(["viscous", "speed_gain"], 0.97, 0.9),  # leads, but holds another effect
            _hyp(["viscous"], 0.02, 0.55, discrepancy=True),
            _hyp(["viscous"], 0.01, 0.2),
            _hyp([], 0.0, 0.0),
        ]
    )
    truth = {"name": "viscous", "magnitude": 0.5}
    assert abs(told_error(truth, summary) - 0.1) < 1e-12  # 0.55 against 0.5, not the lighter 0.2 nor the 0.9
    assert told_error({"name": "air_drag", "magnitude": 1.0}, summary) is None  # never fitted alone


def test_a_log_whose_world_settled_no_push_is_neither_diagnosed_nor_scored(tmp_path, caplog):
    """A world that settles none of a log's pushes leaves a log with no rows: the scoring leaves its label out (and
    says so), and the batch of diagnoses passes the file by instead of stopping the whole batch."""
    from imply.cli import main
    from imply.realworld.benchmark import measured

    labels = {"log-000": {"pushes": {"kept": [True, False]}}, "log-001": {"pushes": {"kept": [False, False]}}}
    with caplog.at_level("WARNING", logger="imply"):
        assert list(measured(labels)) == ["log-000"]
    assert "log-001 left out" in caplog.text
    (tmp_path / "log-001.csv").write_text("object_id,speed,direction,displacement\n")
    out = tmp_path / "reports"
    assert main(["study", "gap", "diagnose-many", str(tmp_path / "log-001.csv"), "-o", str(out)]) == 0
    assert not (out / "log-001").exists()  # no report folder for it
