"""Precision-recall sweeps and place metrics on hand-made score lists."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from driftmap.core.place_recognition.metrics import evaluate_matches, fit_calibration, pr_curve, reliability
from driftmap.errors import BadInputError

TOL = 1e-12


class TestPrCurve:
    def test_hand_computed_curve(self) -> None:
        curve = pr_curve(np.array([0.9, 0.8, 0.7, 0.6, 0.5]), np.array([True, True, False, True, False]), 5)
        assert np.allclose(curve.precision, [1.0, 1.0, 2 / 3, 3 / 4, 3 / 5], atol=TOL)
        assert np.allclose(curve.recall, [0.2, 0.4, 0.4, 0.6, 0.6], atol=TOL)
        assert np.allclose(curve.thresholds, [0.9, 0.8, 0.7, 0.6, 0.5], atol=TOL)
        assert curve.auc == pytest.approx(0.2 + 0.2 + 0.2 * 0.75)
        assert curve.recall_at_full_precision == pytest.approx(0.4)

    def test_ties_are_taken_together(self) -> None:
        curve = pr_curve(np.array([0.9, 0.9, 0.1]), np.array([True, False, True]), 3)
        assert np.allclose(curve.precision, [0.5, 2 / 3], atol=TOL)
        assert curve.recall_at_full_precision == 0.0

    def test_wrong_top_match_and_unscored_frames(self) -> None:
        curve = pr_curve(np.array([0.9, np.nan, 0.5]), np.array([False, True, True]), 3)
        assert curve.recall_at_full_precision == 0.0
        assert curve.recall[-1] == pytest.approx(1 / 3)  # the NaN frame counts in recall, never matches

    def test_perfect_ranking(self) -> None:
        curve = pr_curve(np.array([3.0, 2.0, 1.0]), np.array([True, True, True]), 3)
        assert curve.auc == pytest.approx(1.0)
        assert curve.recall_at_full_precision == pytest.approx(1.0)

    def test_bad_input_names_the_field(self) -> None:
        with pytest.raises(BadInputError, match="one shape"):
            pr_curve(np.zeros(3), np.zeros(2, dtype=bool), 3)
        with pytest.raises(BadInputError, match="no query"):
            pr_curve(np.zeros(3), np.zeros(3, dtype=bool), 0)


def test_evaluate_matches_counts_only_recallable_queries() -> None:
    gt = np.array([[True, False, False], [False, True, False], [False, False, False]])
    best = np.array([0, 2, 1])
    metrics, curve = evaluate_matches(best, np.array([0.9, 0.8, 0.7]), gt)
    assert metrics.recallable == 2 and metrics.queries == 3
    assert metrics.recall_at_1 == pytest.approx(0.5)
    assert metrics.recall_at_full_precision == pytest.approx(0.5)
    assert curve.precision[0] == pytest.approx(1.0)


class TestCalibration:
    def test_platt_fit_is_increasing_pinned_at_zero_and_ranks_like_the_raw_score(self) -> None:
        rng = np.random.default_rng(4)
        raw = rng.uniform(0.0, 1.0, 4000)
        right = rng.uniform(0.0, 1.0, 4000) < 0.2 + 0.75 * raw  # P(right) rises with raw
        knots = fit_calibration(raw, right)
        values = [v for _x, v in knots]
        assert knots[0] == (0.0, 0.0) and knots[-1][0] == 1.0
        assert all(b > a for a, b in itertools.pairwise(values))
        mid = dict(knots)[0.5]
        assert abs(mid - 0.575) < 0.06  # the generating P(right) at raw 0.5

    def test_needs_right_and_wrong_frames(self) -> None:
        with pytest.raises(ValueError, match="both right and wrong"):
            fit_calibration(np.array([0.1, 0.9]), np.array([True, True]))

    def test_reliability_bins_and_error(self) -> None:
        conf = np.array([0.05, 0.05, 0.95, 0.95, np.nan])
        right = np.array([False, True, True, True, False])
        rel = reliability(conf, right, bins=10)
        assert rel.counts.tolist() == [2, 0, 0, 0, 0, 0, 0, 0, 0, 2]  # the NaN (lost) frame left out
        assert rel.right_share[0] == 0.5 and rel.right_share[-1] == 1.0
        assert rel.expected_calibration_error == pytest.approx((2 * 0.45 + 2 * 0.05) / 4)
