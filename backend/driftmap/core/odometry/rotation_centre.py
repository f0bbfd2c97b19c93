"""Rotation-centre self-calibration of the bird's-eye odometry (beyond the paper).

The arc model (:mod:`driftmap.core.odometry.drive`) turns the lateral motion of the ROI centre ``C`` into a
heading change through the lever arm ``x_C + y_c``: ``theta ~ dy_C / (x_C + d / 2 + y_c)``. ``y_c`` (rear
axle to camera, from ``drive.json``) is where the vehicle's no-slip point is assumed to be; tyre slip, a
bogie, an articulated frame or a mis-measured mount move the effective point, and a wrong lever under- or
over-reads every turn alike (8 % under on KITTI clip 2, whose floor motion puts it ~0.3 m behind the
camera, not 1.0 m: a 0.14 rad heading error after a 98 degree turn). The floor's own rotation (the
direction from the near-slice to the far-slice match, in both frames, :func:`direct_turn`) does not depend
on the lever but is noisy (a ~2 m baseline against the ~9 m lever arm), so it calibrates ``y_c`` once
per drive: the ``y_c`` whose arc headings best fit the direct ones (least squares on the heading, residuals
beyond 3 MADs dropped, then refitted). It is applied only when well determined: its standard error moves
the heading gain ``1 / (x_C + d / 2 + y_c)`` by at most ``max_gain_se``. A straight drive leaves it
unobservable and keeps the configured ``y_c``.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

__all__ = ["direct_turn", "fit_rotation_centre"]

MIN_TURN_STEPS = 10  # fewer usable steps than this: the rotation centre is not fitted
LEVER_SEARCH_M = 5.0  # the rotation centre is searched this far either side of the configured y_c
LEVER_GRID = 2001  # candidate rotation centres in that range (then refined by a parabola)


def direct_turn(
    near: tuple[NDArray[np.float64], NDArray[np.float64]],
    far: tuple[NDArray[np.float64], NDArray[np.float64]],
) -> float:
    """Heading change (radians, counter-clockwise) from the near- and far-slice floor matches.

    Args:
        near: ``(2,)`` floor points (look frame, metres) of the near match in the previous and the
            current frame.
        far: the same for the far match.
    """
    v1 = np.asarray(far[0], dtype=np.float64) - np.asarray(near[0], dtype=np.float64)
    v2 = np.asarray(far[1], dtype=np.float64) - np.asarray(near[1], dtype=np.float64)
    turn = math.atan2(float(v1[1]), float(v1[0])) - math.atan2(float(v2[1]), float(v2[0]))
    return math.remainder(turn, math.tau)


def fit_rotation_centre(
    prev_m: NDArray[np.float64],
    curr_m: NDArray[np.float64],
    turn_rad: NDArray[np.float64],
    y_c_m: float,
    max_gain_se: float,
) -> tuple[float, float] | None:
    """The rotation-centre lever ``y_c`` that best explains the directly measured turns, if well determined.

    Args:
        prev_m: ``(N, 2)`` float64 floor points (look frame, metres) of the ROI-centre match in the
            previous frame of each usable step.
        curr_m: ``(N, 2)`` the same points in the current frame.
        turn_rad: ``(N,)`` float64 direct heading changes (:func:`direct_turn`), radians.
        y_c_m: the configured lever (rear axle to camera), metres: the centre of the search.
        max_gain_se: largest standard error of the heading gain, as a fraction of it, that is applied.

    Returns:
        ``(y_c_m, standard_error_m)`` of the fit, or None when too few steps, not observable or not
        determined well enough.
    """
    p1, p2 = np.asarray(prev_m, dtype=np.float64), np.asarray(curr_m, dtype=np.float64)
    turn = np.asarray(turn_rad, dtype=np.float64)
    if p1.ndim != 2 or p1.shape[1] != 2 or p1.shape != p2.shape or turn.shape != (len(p1),):
        raise ValueError(
            f"prev_m, curr_m must be (N, 2) and turn_rad (N,), got {p1.shape}, {p2.shape}, {turn.shape}"
        )
    keep = np.isfinite(turn) & np.all(np.isfinite(p1), axis=1) & np.all(np.isfinite(p2), axis=1)
    lateral = (p1[:, 1] - p2[:, 1])[keep]  # dy_C = theta (x_C + d/2 + y_c), small angles
    base = (p2[:, 0] + 0.5 * (p1[:, 0] - p2[:, 0]))[keep]
    turn = turn[keep]
    fit = None
    for _ in range(2):  # fit, drop residuals beyond 3 MADs, fit again
        if len(turn) < MIN_TURN_STEPS:
            return None
        fit = _least_squares(lateral, base, turn, y_c_m)
        if fit is None:
            return None
        resid = turn - lateral / (base + fit)
        mad = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
        inlier = np.abs(resid) <= 3.0 * mad if mad > 0 else np.ones(len(resid), bool)
        lateral, base, turn = lateral[inlier], base[inlier], turn[inlier]
    assert fit is not None
    arm = base + fit
    resid = turn - lateral / arm
    slope = lateral / arm**2  # -d theta / d y_c
    info = float(np.sum(slope**2))
    if len(turn) <= 1 or info <= 0:
        return None
    se = math.sqrt(float(np.sum(resid**2)) / (len(turn) - 1) / info)
    if se / float(np.median(arm)) > max_gain_se:
        return None
    return fit, se


def _least_squares(
    lateral: NDArray[np.float64], base: NDArray[np.float64], turn: NDArray[np.float64], y_c_m: float
) -> float | None:
    """argmin_y sum (turn - lateral / (base + y))^2 on a grid around y_c_m, refined by a parabola."""
    lo = max(y_c_m - LEVER_SEARCH_M, 0.5 - float(base.min()))  # keep every lever arm above 0.5 m
    hi = y_c_m + LEVER_SEARCH_M
    if hi <= lo:
        return None
    ys = np.linspace(lo, hi, LEVER_GRID)
    cost = np.array([float(np.sum((turn - lateral / (base + y)) ** 2)) for y in ys])
    i = int(np.argmin(cost))
    if i in (0, len(ys) - 1):  # at the edge of the search: not a determined minimum
        return None
    c0, c1, c2 = cost[i - 1], cost[i], cost[i + 1]
    curv = c0 - 2 * c1 + c2
    step = float(ys[1] - ys[0])
    return float(ys[i] + (0.5 * (c0 - c2) / curv * step if curv > 0 else 0.0))
