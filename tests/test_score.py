"""Definitions of implied physics, self and anchored disagreement, on a closed-form table."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from conftest import analytic_log_d
from imply.score import Scorer, score_sets

QUERY = np.array([0.25, 0.4, 0.55, 0.7, 0.85])
CALIB = np.array([0.3, 0.8])


def exact_d(v, m, mu):
    return np.exp(analytic_log_d(np.asarray(v), m, mu))


def test_recovers_an_in_range_object_exactly(analytic_table):
    m, mu = 0.7, 0.23
    s = score_sets(analytic_table, QUERY, exact_d(QUERY, m, mu)[None], CALIB, exact_d(CALIB, m, mu)[None])
    assert s.mass_hat[0] == pytest.approx(m, rel=0.02)
    assert s.friction_hat[0] == pytest.approx(mu, rel=0.02)
    assert s.self_disagreement[0] < 1e-3
    assert s.anchored_disagreement[0] < 1e-3
    assert s.n_rollouts[0] == 5


def test_self_and_anchored_are_rms_residuals_of_the_best_single_object(analytic_table):
    """Compare with a per-set least-squares fit started from many points."""
    rng = np.random.default_rng(3)
    scorer = Scorer(analytic_table)
    lo = np.log([analytic_table.masses[0], analytic_table.frictions[0]])
    hi = np.log([analytic_table.masses[-1], analytic_table.frictions[-1]])
    for _ in range(5):
        y = np.log(exact_d(QUERY, 0.5, 0.3)) + 0.2 * rng.standard_normal(5)
        yc = np.log(exact_d(CALIB, 1.2, 0.15))
        s = scorer.score(QUERY, np.exp(y)[None], CALIB, np.exp(yc)[None])

        def best(speeds, logs):
            def resid(theta):
                return analytic_log_d(speeds, np.exp(theta[0]), np.exp(theta[1])) - logs

            starts = np.stack(
                np.meshgrid(np.linspace(lo[0], hi[0], 4)[1:-1], np.linspace(lo[1], hi[1], 4)[1:-1]), -1
            ).reshape(-1, 2)
            fits = [least_squares(resid, x0, bounds=(lo, hi)) for x0 in starts]
            return min(np.sqrt(2 * f.cost / len(logs)) for f in fits)

        assert s.self_disagreement[0] == pytest.approx(best(QUERY, y), abs=2e-3)
        both_v = np.concatenate([CALIB, QUERY])
        assert s.anchored_disagreement[0] == pytest.approx(best(both_v, np.concatenate([yc, y])), abs=2e-3)
        # adding terms can only raise the best total residual
        assert s.anchored_disagreement[0] ** 2 * 7 >= s.self_disagreement[0] ** 2 * 5 - 1e-9


def test_anchoring_exposes_a_consistent_but_wrong_object(analytic_table):
    truth, typical = (1.5, 0.5), (0.4, 0.15)
    rollouts = exact_d(QUERY, *typical)[None]
    s = score_sets(analytic_table, QUERY, rollouts, CALIB, exact_d(CALIB, *truth)[None])
    assert s.self_disagreement[0] < 1e-3
    assert s.anchored_disagreement[0] > 0.1


def test_frozen_rollouts_are_clamped_to_the_floor(analytic_table):
    s = score_sets(analytic_table, QUERY, np.zeros((1, 5)), CALIB, exact_d(CALIB, 0.5, 0.3)[None], floor=1e-4)
    assert np.isfinite(s.anchored_disagreement[0]) and s.anchored_disagreement[0] > 1.0
    s2 = score_sets(analytic_table, QUERY, np.full((1, 5), 1e-9), CALIB, exact_d(CALIB, 0.5, 0.3)[None], floor=1e-4)
    assert s2.anchored_disagreement[0] == pytest.approx(s.anchored_disagreement[0])


def test_vectorised_equals_one_set_at_a_time_and_handles_ragged_sets(analytic_table):
    rng = np.random.default_rng(0)
    n = 40
    m = np.exp(rng.uniform(np.log(0.2), np.log(2.0), n))
    mu = np.exp(rng.uniform(np.log(0.1), np.log(0.6), n))
    d = exact_d(QUERY[None], m[:, None], mu[:, None]) * np.exp(0.1 * rng.standard_normal((n, 5)))
    d[::3, 4] = np.nan  # some sets have only 4 rollouts
    scorer = Scorer(analytic_table, chunk=7)
    together = scorer.score(QUERY, d)
    for i in range(0, n, 9):
        keep = np.isfinite(d[i])
        alone = Scorer(analytic_table).score(QUERY[keep], d[i, keep][None])
        assert together.self_disagreement[i] == pytest.approx(alone.self_disagreement[0], abs=1e-12)
        assert together.mass_hat[i] == pytest.approx(alone.mass_hat[0])
    assert together.n_rollouts[0] == 4 and together.n_rollouts[1] == 5


def test_refuses_bad_sets(analytic_table):
    scorer = Scorer(analytic_table)
    with pytest.raises(ValueError, match="outside"):
        scorer.score([0.1, 0.5], [[0.1, 0.1]])
    with pytest.raises(ValueError, match="negative"):
        scorer.score(QUERY, -np.ones((1, 5)))
    with pytest.raises(ValueError, match="no terms"):
        scorer.score(QUERY, np.full((1, 5), np.nan))


def test_blocked_search_and_speed_slices_match_the_direct_evaluation(analytic_table):
    """Blocks of any size and the per-speed splines give the scores of the table's own 3-D spline."""
    rng = np.random.default_rng(7)
    n = 300
    m = np.exp(rng.uniform(np.log(0.2), np.log(2.0), n))
    mu = np.exp(rng.uniform(np.log(0.1), np.log(0.6), n))
    d = exact_d(QUERY[None], m[:, None], mu[:, None]) * np.exp(0.1 * rng.standard_normal((n, 5)))
    d[::4, 1] = np.nan  # a second count pattern
    dc = exact_d(CALIB[None], m[:, None], mu[:, None])
    fast = Scorer(analytic_table, chunk=128, block_bytes=1 << 16).score(QUERY, d, CALIB, dc)
    direct = Scorer(analytic_table)
    direct._slices = lambda uniq: None  # every term through PushTable.log_displacement
    ref = direct.score(QUERY, d, CALIB, dc)
    for name in ("self_disagreement", "anchored_disagreement", "mass_hat", "anchored_friction_hat"):
        np.testing.assert_allclose(getattr(fast, name), getattr(ref, name), rtol=1e-10, atol=1e-12)


def test_threads_give_the_same_scores(analytic_table):
    rng = np.random.default_rng(8)
    d = exact_d(QUERY[None], 0.7, 0.3) * np.exp(0.2 * rng.standard_normal((50, 5)))
    one = Scorer(analytic_table, chunk=8).score(QUERY, d)
    two = Scorer(analytic_table, chunk=8, threads=2).score(QUERY, d)
    np.testing.assert_array_equal(one.self_disagreement, two.self_disagreement)
    np.testing.assert_array_equal(one.mass_hat, two.mass_hat)
