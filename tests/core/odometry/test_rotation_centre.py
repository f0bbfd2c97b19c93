"""Tests of driftmap.core.odometry.rotation_centre: the rotation-centre fit on synthetic floor matches."""

from __future__ import annotations

import math

import numpy as np
import pytest

from driftmap.core.odometry.rotation_centre import direct_turn, fit_rotation_centre

SEED = 5
TURN_NOISE_RAD = 0.006  # per-step noise of the direct (near/far) turn, like KITTI clip 2's
LEVER_TOL_M = 0.3  # fitted rotation centre (about 2 standard errors at this noise)
MAX_GAIN_SE = 0.025


def arc_pairs(
    rng: np.random.Generator, n: int, y_c_true: float, turns: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """ROI-centre matches ~8.5 m ahead of the camera for rear-axle arcs about a centre y_c_true behind it."""
    curr = np.stack([8.5 + rng.normal(0, 0.3, n), rng.normal(0, 0.2, n)], axis=1)
    prev = np.empty_like(curr)
    for k, theta in enumerate(turns):
        d = 1.0 + 0.2 * rng.standard_normal()
        tx = d * math.cos(theta / 2) + y_c_true * (math.cos(theta) - 1)
        ty = d * math.sin(theta / 2) + y_c_true * math.sin(theta)
        c, s = math.cos(theta), math.sin(theta)
        prev[k] = [c * curr[k, 0] - s * curr[k, 1] + tx, s * curr[k, 0] + c * curr[k, 1] + ty]
    return prev, curr


class TestFitRotationCentre:
    def test_recovers_a_centre_behind_the_configured_one(self) -> None:
        rng = np.random.default_rng(SEED)
        turns = -0.045 * np.abs(np.sin(np.linspace(0, 2 * math.pi, 100))) - 0.005  # two right-hand bends
        prev, curr = arc_pairs(rng, 100, 0.3, turns)
        fit = fit_rotation_centre(prev, curr, turns + rng.normal(0, TURN_NOISE_RAD, 100), 1.0, MAX_GAIN_SE)
        assert fit is not None
        assert fit[0] == pytest.approx(0.3, abs=LEVER_TOL_M)
        assert 0 < fit[1] < LEVER_TOL_M

    def test_outliers_do_not_move_it(self) -> None:
        rng = np.random.default_rng(SEED + 1)
        turns = 0.04 * np.sin(np.linspace(0, 6 * math.pi, 200))
        prev, curr = arc_pairs(rng, 200, 1.8, turns)
        measured = turns + rng.normal(0, TURN_NOISE_RAD, 200)
        measured[[5, 17, 40]] = [0.3, -0.25, 0.2]  # failed slice matches
        fit = fit_rotation_centre(prev, curr, measured, 1.0, MAX_GAIN_SE)
        assert fit is not None and fit[0] == pytest.approx(1.8, abs=LEVER_TOL_M)

    def test_a_straight_drive_leaves_it_unobservable(self) -> None:
        rng = np.random.default_rng(SEED + 2)
        turns = rng.normal(0, 0.0007, 50)  # KITTI clip 1: a straight road
        prev, curr = arc_pairs(rng, 50, 1.0, turns)
        assert fit_rotation_centre(prev, curr, turns + rng.normal(0, 0.003, 50), 1.0, MAX_GAIN_SE) is None

    def test_too_few_steps(self) -> None:
        rng = np.random.default_rng(SEED + 3)
        turns = np.full(5, -0.04)
        prev, curr = arc_pairs(rng, 5, 0.3, turns)
        assert fit_rotation_centre(prev, curr, turns, 1.0, MAX_GAIN_SE) is None

    def test_rejects_bad_shapes(self) -> None:
        with pytest.raises(ValueError):
            fit_rotation_centre(np.zeros((4, 2)), np.zeros((4, 3)), np.zeros(4), 1.0, MAX_GAIN_SE)


class TestDirectTurn:
    @pytest.mark.parametrize("theta", [0.0, 0.05, -0.12, 3.1])
    def test_rotation_of_the_near_far_direction(self, theta: float) -> None:
        c, s = math.cos(theta), math.sin(theta)
        near2, far2 = np.array([7.5, 0.3]), np.array([9.4, -0.2])
        t = np.array([1.1, -0.05])
        near1 = np.array([c * near2[0] - s * near2[1], s * near2[0] + c * near2[1]]) + t
        far1 = np.array([c * far2[0] - s * far2[1], s * far2[0] + c * far2[1]]) + t
        assert direct_turn((near1, near2), (far1, far2)) == pytest.approx(theta, abs=1e-12)
