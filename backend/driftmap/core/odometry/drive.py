"""Ground-plane visual odometry of a drive ([SSLAM] III-A-1, eq. 1 and 2): its steps, their
self-calibration, and dead reckoning.

One step between two frames (the linear and homography models, the signs and the rear-axle arc motion
model) is :mod:`driftmap.core.odometry.step`; the grid each model samples and the per-frame preparation
are :mod:`driftmap.core.odometry.grid`. A drive's frames are matched in order (:func:`match_frames`, also
per segment of a long drive), then self-calibrated and integrated (:func:`reckon`); :func:`dead_reckon`
does both.

Horizon self-calibration (homography model): a camera pitch error shifts the
true horizon by ``delta`` pixels, ``H_true(u, v) = H(u, v + delta)``, and scales floor motion by a
depth-dependent factor (about 17 % on the KITTI clips). Floor motion is rigid, so the distance
between matched points in the nearest and the farthest slice of the ROI footprint must be the
same in both frames; each moving step yields the ``delta`` that makes it so, and the median over
the drive is applied to every step at the end, except where the camera's pitch demonstrably varies
along the drive (a ramp, a loaded tray: :mod:`driftmap.core.odometry.pitch` tracks it over ~12 m of
travel and applies the local value there). :func:`shift_horizon` gives the corrected camera
for later single steps. Camera height (the overall scale) is not observable this way. The same pass
self-calibrates the rotation centre (the lever ``y_c`` of the arc) from the floor's own rotation
between the near and far slices, when the drive turns enough to determine it
(:mod:`driftmap.core.odometry.rotation_centre`).

Poses are of the camera's floor point ``[x_m, y_m, yaw_rad]`` (x forward, y left), counter-clockwise
positive.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Iterable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.grid import GridFrame, apply_homography, check_frame, match_grid, prepare_frame
from driftmap.core.odometry.params import ODOMETRY_DEFAULT, OdometryParams
from driftmap.core.odometry.pitch import horizon_floor
from driftmap.core.odometry.rotation_centre import direct_turn, fit_rotation_centre
from driftmap.core.odometry.step import (
    OdometryStep,
    Pair,
    centre_px,
    estimate_step,
    finish_step,
    match_step,
    solve_arc,
)
from driftmap.errors import BadInputError

__all__ = [
    "DeadReckoning",
    "MatchedSteps",
    "OdometryStep",
    "compose",
    "dead_reckon",
    "estimate_step",
    "match_frames",
    "reckon",
    "shift_horizon",
]


@dataclass(frozen=True)
class DeadReckoning:
    """Integrated odometry of a frame sequence.

    Attributes:
        wTi: ``(N, 3)`` float64 world poses ``[x_m, y_m, yaw_rad]`` of the camera foot per frame.
        steps: the ``N - 1`` steps between consecutive frames.
        ms_per_step: ``(N - 1,)`` float64 wall-clock milliseconds per step (frame preparation included).
        horizon_offset_px: horizon offset applied by the self-calibration (0 when off or unobservable).
        lever_m: the rotation-centre lever arm (rear axle to camera, metres) the steps were solved with:
            the camera's ``y_c_m``, or the self-calibrated one when it was well determined.
        lever_se_m: the standard error of the self-calibrated lever, metres; None when the drive's turns did
            not determine it (``lever_m`` is then the camera's).
    """

    wTi: NDArray[np.float64]
    steps: list[OdometryStep]
    ms_per_step: NDArray[np.float64]
    horizon_offset_px: float
    lever_m: float
    lever_se_m: float | None = None


def _horizon_offset(hom: NDArray, pairs: list[Pair], max_px: float) -> float | None:
    """Horizon offset that keeps the near-far distance of one step's matched floor points rigid."""
    if len(pairs) < 3 or min(abs(p[1][1] - p[0][1]) for p in pairs[1:]) < 2.0:
        return None
    (n1, n2), (f1, f2) = pairs[1], pairs[2]
    pts = np.stack([n1, f1, n2, f2])

    def gap(delta: float) -> float:
        shifted = pts + np.array([0.0, delta])
        if np.any(shifted @ hom[2, :2] + hom[2, 2] <= 0):
            return math.nan
        f = apply_homography(hom, shifted)
        near, far = f[0] - f[1], f[2] - f[3]
        return math.sqrt(near.dot(near)) - math.sqrt(far.dot(far))  # np.linalg.norm's own sums

    # The bracketing grid interval nearest 0 (the first on ties); intervals are tried nearest first,
    # so only the gap values near 0 are computed, not all 81.
    grid = np.linspace(-max_px, max_px, 81)
    vals: dict[int, float] = {}

    def val(j: int) -> float:
        if j not in vals:
            vals[j] = gap(float(grid[j]))
        return vals[j]

    for i in sorted(range(80), key=lambda j: (abs(grid[j]), j)):
        if math.isfinite(val(i) + val(i + 1)) and val(i) * val(i + 1) <= 0:
            break
    else:
        return None
    lo, hi, g_lo = float(grid[i]), float(grid[i + 1]), val(i)
    for _ in range(40):
        mid = 0.5 * (lo + hi)
        g_mid = gap(mid)
        lo, hi, g_lo = (mid, hi, g_mid) if g_lo * g_mid > 0 else (lo, mid, g_lo)
    return 0.5 * (lo + hi)


def shift_horizon(camera: CameraModel, offset_px: float) -> CameraModel:
    """The camera with its ground homography's horizon moved by ``offset_px`` pixels.

    ``H'(u, v) = H(u, v + offset_px)`` (a small pitch change); ``k_x``, ``k_y`` and ``y_h`` are
    recomputed at the ROI centre (``k`` as the floor metres per pixel step along u and v).

    Raises:
        ValueError: the camera has no ground homography.
    """
    hom = camera.homography()
    if hom is None:
        raise ValueError("shift_horizon needs a camera with ground_homography")
    shifted = hom @ np.array([[1.0, 0.0, 0.0], [0.0, 1.0, offset_px], [0.0, 0.0, 1.0]])
    c = centre_px(camera.ground_roi_px)
    step_u, step_v = np.array([0.5, 0.0]), np.array([0.0, 0.5])
    f = apply_homography(shifted, np.stack([c, c + step_u, c - step_u, c + step_v, c - step_v]))
    return dataclasses.replace(
        camera,
        k_x_m_per_px=float(np.linalg.norm(f[1] - f[2])),
        k_y_m_per_px=float(np.linalg.norm(f[3] - f[4])),
        y_h_m=float(np.hypot(*f[0])),
        ground_homography=tuple((float(r[0]), float(r[1]), float(r[2])) for r in shifted),
    )


def compose(wTa: NDArray | tuple[float, ...], aTb: NDArray | tuple[float, ...]) -> NDArray[np.float64]:
    """SE(2) ``wTb = wTa * aTb`` of ``(3,)`` poses ``[x_m, y_m, yaw_rad]``; yaw wrapped to (-pi, pi]."""
    x, y, yaw = (float(v) for v in wTa)
    dx, dy, dyaw = (float(v) for v in aTb)
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array(
        [x + c * dx - s * dy, y + s * dx + c * dy, math.atan2(math.sin(yaw + dyaw), math.cos(yaw + dyaw))]
    )


def _usable(step: OdometryStep, params: OdometryParams) -> bool:
    """Whether a step's matches take part in the self-calibration (moving, confident)."""
    return not step.stationary and step.confidence >= params.stationary_min_confidence


def _step_horizon(
    step: OdometryStep, pairs: list[Pair], hom: NDArray | None, params: OdometryParams
) -> float:
    """The horizon offset one step's near/far match implies, pixels (NaN: unusable or unobservable)."""
    if hom is None or not params.self_calibrate or not _usable(step, params):
        return math.nan
    found = _horizon_offset(hom, pairs, params.horizon_max_px)
    return math.nan if found is None else found


def _self_calibrate(
    steps: list[OdometryStep],
    pairs: list[list[Pair]],
    estimates: NDArray[np.float64],
    camera: CameraModel,
    hom: NDArray,
    params: OdometryParams,
) -> tuple[float, float, float | None]:
    """The drive's horizon offset (median of the steps' ``estimates``, :func:`_step_horizon`; tracked where
    the pitch demonstrably varies, :mod:`driftmap.core.odometry.pitch`) and rotation centre
    (:mod:`driftmap.core.odometry.rotation_centre`); re-solves ``steps`` in place with both. Returns the median offset
    (0 when unobservable, steps then untouched), the lever arm used and its standard error (None: the
    camera's), metres."""
    usable = [_usable(s, params) for s in steps]
    tracked = horizon_floor(hom, pairs, estimates, params.pitch_window_m, params.pitch_gate_z)
    if tracked is None:  # fewer than 3 estimates
        return 0.0, camera.y_c_m, None
    offset, floor = tracked[0].median_px, tracked[1]  # median; local pitch where it demonstrably varies
    lever, lever_se = camera.y_c_m, None
    if params.calibrate_lever:
        rows = [k for k, (u, f) in enumerate(zip(usable, floor, strict=True)) if u and len(f) == 3]
        fit = fit_rotation_centre(
            np.array([floor[k][0][0] for k in rows]).reshape(-1, 2),
            np.array([floor[k][0][1] for k in rows]).reshape(-1, 2),
            np.array([direct_turn(floor[k][1], floor[k][2]) for k in rows], dtype=np.float64),
            camera.y_c_m,
            params.lever_max_gain_se,
        )
        if fit is not None:
            lever, lever_se = fit
    solved = dataclasses.replace(camera, y_c_m=lever)
    for k, (s, f) in enumerate(zip(steps, floor, strict=True)):
        if not s.stationary and f:
            d, theta = solve_arc(f[0][0], f[0][1], lever)
            steps[k] = finish_step(d, theta, s.shift_px, s.confidence, solved, s.model, params)
    return offset, lever, lever_se


@dataclass(frozen=True)
class MatchedSteps:
    """The steps between consecutive frames of a run of a drive, before the drive's self-calibration.

    Attributes:
        steps: the S steps, in frame order.
        pairs: per step, its matched pixels ([ROI centre, near slice, far slice] with the homography
            model and self-calibration, [ROI centre] without it, none with the linear model).
        ms_per_step: ``(S,)`` float64 wall-clock milliseconds per step (frame preparation included).
        frames: frames given (warm-up included).
        horizon_px: ``(S,)`` float64 horizon offset each step's near/far match implies, pixels (NaN where
            the step is unusable or it is unobservable); the self-calibration's per-step input, computed
            where the step is (in parallel), not at the join.
    """

    steps: list[OdometryStep]
    pairs: list[list[Pair]]
    ms_per_step: NDArray[np.float64]
    frames: int
    horizon_px: NDArray[np.float64]


def match_frames(
    frames: Iterable[NDArray] | NDArray,
    camera: CameraModel,
    params: OdometryParams = ODOMETRY_DEFAULT,
    *,
    warm_up: int = 0,
    first_index: int = 0,
) -> MatchedSteps:
    """The steps between consecutive frames; each frame is prepared once.

    A run that starts inside a drive (a segment) is given ``warm_up`` frames before its own: the steps
    into them only set the motion prior of the next search and are not returned.

    Args:
        frames: ``(N, H, W)`` uint8 stack or an iterable of ``(H, W)`` uint8 frames in time order.
        camera: the drive's camera.
        params: odometry parameters.
        warm_up: leading steps matched but not returned.
        first_index: the drive's index of the first frame given (for errors).

    Raises:
        BadInputError: a frame of the wrong shape.
    """
    setup = match_grid(camera, params)
    hom = camera.homography() if setup.model == "homography" else None
    steps: list[OdometryStep] = []
    pairs: list[list[Pair]] = []
    horizons: list[float] = []
    times: list[float] = []
    prev: GridFrame | None = None
    n_frames = 0
    for k, frame in enumerate(frames):
        t0 = time.perf_counter()
        curr = prepare_frame(check_frame(frame, camera, f"frame {first_index + k}"), camera, setup, params)
        n_frames += 1
        if prev is not None:
            step, pair = match_step(prev, curr, camera, setup, params, steps[-1].shift_px if steps else None)
            steps.append(step)
            pairs.append(pair)
            horizons.append(_step_horizon(step, pair, hom, params))
            times.append(1e3 * (time.perf_counter() - t0))
        prev = curr
    w = warm_up
    return MatchedSteps(
        steps[w:], pairs[w:], np.asarray(times[w:], dtype=np.float64), n_frames, np.asarray(horizons[w:])
    )


def _start_pose(start_wT: tuple[float, float, float]) -> NDArray[np.float64]:
    """``start_wT`` as a ``(3,)`` array. Raises BadInputError unless it is three finite numbers."""
    start = np.asarray(start_wT, dtype=np.float64)
    if start.shape != (3,) or not np.all(np.isfinite(start)):
        raise BadInputError(f"must be finite (x_m, y_m, yaw_rad), got {start_wT}", field="start_wT")
    return start


def reckon(
    matched: MatchedSteps,
    camera: CameraModel,
    params: OdometryParams = ODOMETRY_DEFAULT,
    start_wT: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> DeadReckoning:
    """Self-calibrate a whole drive's steps and integrate them (the second half of :func:`dead_reckon`).

    Args:
        matched: every step of the drive, in order (e.g. its segments' joined).
        camera: the drive's camera.
        params: odometry parameters (as the steps were matched with).
        start_wT: world pose ``(x_m, y_m, yaw_rad)`` of the camera foot at the first frame.

    Returns:
        :class:`DeadReckoning` with S + 1 poses.

    Raises:
        BadInputError: a bad start pose.
    """
    start = _start_pose(start_wT)
    steps = list(matched.steps)
    offset, lever, lever_se = 0.0, camera.y_c_m, None
    hom = camera.homography()
    if params.self_calibrate and steps and steps[0].model == "homography" and hom is not None:
        offset, lever, lever_se = _self_calibrate(
            steps, matched.pairs, matched.horizon_px, camera, hom, params
        )
    poses = [start]
    for s in steps:
        poses.append(compose(poses[-1], s.prev_T_curr))
    return DeadReckoning(np.stack(poses), steps, matched.ms_per_step, offset, lever, lever_se)


def dead_reckon(
    frames: Iterable[NDArray] | NDArray,
    camera: CameraModel,
    params: OdometryParams = ODOMETRY_DEFAULT,
    start_wT: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> DeadReckoning:
    """Integrate the steps of a frame sequence (:func:`match_frames`, then :func:`reckon`).

    With ``params.self_calibrate`` and the homography model, the horizon offset is estimated from
    the whole sequence (median of the moving, confident steps' estimates, needs at least 3; tracked
    along the drive where the pitch demonstrably varies) and every step is re-solved with it before
    integration.

    Args:
        frames: ``(N, H, W)`` uint8 stack or an iterable of ``(H, W)`` uint8 frames in time order.
        camera: the drive's camera.
        params: odometry parameters.
        start_wT: world pose ``(x_m, y_m, yaw_rad)`` of the camera foot at the first frame.

    Returns:
        :class:`DeadReckoning`: ``wTi`` ``(N, 3)``, ``N - 1`` steps, timings, horizon offset.

    Raises:
        BadInputError: a frame of the wrong shape or a bad start pose.
    """
    _start_pose(start_wT)  # a bad start fails before any frame is matched
    matched = match_frames(frames, camera, params)
    if matched.frames == 0:
        return DeadReckoning(np.zeros((0, 3)), [], np.zeros(0), 0.0, camera.y_c_m)
    return reckon(matched, camera, params, start_wT)
