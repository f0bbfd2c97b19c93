"""Precision-recall curves of hand-made score lists."""

from __future__ import annotations

import numpy as np
import pytest

from driftmap.reports.pr_curves import pr_curve

TOL = 1e-12


class TestPrCurve:
    def test_hand_computed_curve(self) -> None:
        curve = pr_curve(np.array([0.9, 0.8, 0.7, 0.6, 0.5]), np.array([True, True, False, True, False]))
        assert np.allclose(curve.precision, [1.0, 1.0, 2 / 3, 3 / 4, 3 / 5], atol=TOL)
        assert np.allclose(curve.recall, [0.2, 0.4, 0.4, 0.6, 0.6], atol=TOL)
        assert curve.auc == pytest.approx(0.2 + 0.2 + 0.2 * 0.75)
        assert curve.recall_at_full_precision == pytest.approx(0.4)
        assert curve.threshold_at_full_precision() == pytest.approx(0.8)

    def test_ties_are_taken_together(self) -> None:
        curve = pr_curve(np.array([0.9, 0.9, 0.1]), np.array([True, False, True]))
        assert np.allclose(curve.precision, [0.5, 2 / 3], atol=TOL)
        assert curve.recall_at_full_precision == 0.0

    def test_wrong_top_match_and_unscored_frames(self) -> None:
        curve = pr_curve(np.array([0.9, np.nan, 0.5]), np.array([False, True, True]))
        assert curve.recall_at_full_precision == 0.0
        assert curve.recall[-1] == pytest.approx(1 / 3)  # the NaN frame counts in recall, never matches

    def test_perfect_ranking(self) -> None:
        curve = pr_curve(np.array([3.0, 2.0, 1.0]), np.array([True, True, True]))
        assert curve.auc == pytest.approx(1.0)
        assert curve.recall_at_full_precision == pytest.approx(1.0)

    def test_shapes_must_agree(self) -> None:
        with pytest.raises(ValueError, match="must be"):
            pr_curve(np.zeros(3), np.zeros(2, dtype=bool))
