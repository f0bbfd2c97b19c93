"""Odometry self-calibration: a known scale and heading-rate bias is recovered and removed."""

from __future__ import annotations

import numpy as np
import pytest

from driftmap.core.alignment import dead_reckon
from driftmap.core.odometry_calibration import NO_BIAS, OdometryBias, apply_bias, estimate_bias
from driftmap.errors import BadInputError

SCALE_TOL = 0.003  # fitted scale within this of the truth
RATE_TOL = 2e-4  # fitted heading rate within this of the truth, rad/m


def true_steps(n: int = 1500, seed: int = 0) -> np.ndarray:
    """(n, 3) steps of a vehicle driving 0.5 m a frame, turning gently, reversing for a stretch."""
    rng = np.random.default_rng(seed)
    dx = np.full(n, 0.5)
    dx[600:700] = -0.3  # reversing
    dtheta = 0.01 * np.sin(np.arange(n) / 40.0) + rng.normal(0.0, 0.002, n)
    return np.column_stack([dx, rng.normal(0.0, 0.002, n), dtheta])


def measured(steps: np.ndarray, bias: OdometryBias) -> np.ndarray:
    """What a biased odometry reports for ``steps``."""
    out = steps.copy()
    out[:, :2] /= bias.scale
    out[:, 2] += bias.yaw_rate_rad_per_m * out[:, 0]
    return out


class TestEstimateBias:
    def test_recovers_a_known_bias_and_apply_removes_it(self) -> None:
        truth = true_steps()
        bias = OdometryBias(1.02, np.radians(0.6))
        raw = measured(truth, bias)
        wTi = dead_reckon(truth, np.array([10.0, -4.0, 0.3]))
        fitted = estimate_bias(raw, wTi)
        assert fitted.scale == pytest.approx(bias.scale, abs=SCALE_TOL)
        assert fitted.yaw_rate_rad_per_m == pytest.approx(bias.yaw_rate_rad_per_m, abs=RATE_TOL)
        assert np.allclose(apply_bias(raw, fitted), truth, atol=2e-3)

    def test_unbiased_odometry_gives_no_correction(self) -> None:
        truth = true_steps(seed=1)
        fitted = estimate_bias(truth, dead_reckon(truth))
        assert fitted.scale == pytest.approx(1.0, abs=1e-9)
        assert fitted.yaw_rate_rad_per_m == pytest.approx(0.0, abs=1e-9)

    def test_standing_still_gives_no_bias(self) -> None:
        still = np.zeros((50, 3))
        assert estimate_bias(still, dead_reckon(still)) == NO_BIAS

    def test_shapes_are_checked(self) -> None:
        with pytest.raises(BadInputError, match="wTi"):
            estimate_bias(np.zeros((5, 3)), np.zeros((5, 3)))
