"""One ground-plane odometry step ([SSLAM] III-A-1, eq. 1 and 2): the vehicle's motion between two frames.

Two consecutive frames are compared over the calibrated floor region (``ground_roi``); the motion
of the floor content is found by coarse-to-fine, sub-pixel, two-sided SAD registration
(:func:`driftmap.core.imaging.registration.register_shift`) of patch-normalised images. Two models turn it into
vehicle motion:

* **linear** (the paper): the ROI is split into ``linear_patches`` (the paper's tracked patches;
  one translation cannot fit a whole ROI seen in perspective), matched after a light blur (fine
  grain does not survive the zoom between frames); the median patch shift ``(x_p, y_p)`` pixels
  gives ``theta = atan(x_p k_x / (y_c + y_h))`` (eq. 1) and ``d = y_p k_y forward_sign`` (eq. 2).
* **homography** (beyond the paper): frames are warped through ``ground_homography`` into a
  metric bird's-eye grid (``bev_res_m`` cells; rows point backwards, columns right), where a shift
  is floor motion in metres whatever the perspective. The floor point ``C`` at the ROI-footprint
  centre and its match in the current frame give ``(d, theta)`` of a rear-axle arc (the lever-arm
  geometry of eq. 1, no sideways slip); the current frame is then re-warped rotated by ``theta``
  about ``C``, removing the shear of a turn, and matched and solved again.

The grid each model samples and the per-frame preparation live in :mod:`driftmap.core.odometry.grid`;
a drive's steps, their self-calibration and dead reckoning in :mod:`driftmap.core.odometry.drive`.

Signs. ``theta`` is counter-clockwise (left turn) positive. Floor content moves right in the
image (+u) when the vehicle turns left, for forward- and rear-looking cameras alike (the camera
yaws left with the vehicle), so ``x_p > 0`` gives ``theta > 0``.

Look frame. Both models measure the motion in the camera's *look frame*: x the way the camera looks, y
left of it, origin at the camera's foot, ``y_c`` the rear axle to the camera along x (the frame of
``ground_homography``). ``forward_sign = +1``: the camera looks ahead and the look frame is the vehicle's;
content moves down (+v) when driving forward, so ``d = +y_p k_y``. ``forward_sign = -1``: the camera looks
behind, the look frame is the vehicle's turned half a turn, and :func:`finish_step` turns the step into the
vehicle's frame (travel and displacement negated, the turn kept). Reversing gives ``d < 0``.

Motion model (rear-axle arc, midpoint heading). Poses are of the camera's floor point, ``y_c`` from the
rear axle along the look direction. In a step the rear axle travels ``d`` along the chord at the midpoint
heading ``theta / 2``, so the camera foot moves by ``t = d (cos theta/2, sin theta/2) + y_c (cos theta - 1,
sin theta)`` in the previous look frame and ``wT_{k+1} = wT_k * (t, theta)`` (SE(2): translate, then
rotate); poses are reported in the vehicle's frame (x forward, y left).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.images import mask_pyramid
from driftmap.core.imaging.registration import register_shift
from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.grid import (
    GridFrame,
    MatchGrid,
    Rect,
    apply_homography,
    check_frame,
    grid_coords,
    grid_masks,
    match_grid,
    normalised_pyramid,
    prepare_frame,
    warp_to_grid,
)
from driftmap.core.odometry.params import ODOMETRY_DEFAULT, OdometryParams

__all__ = ["OdometryStep", "Pair", "centre_px", "estimate_step", "finish_step", "match_step", "solve_arc"]

Pair = tuple[NDArray[np.float64], NDArray[np.float64]]  # matched pixels (previous frame, current frame)


@dataclass(frozen=True)
class OdometryStep:
    """Motion of the vehicle between two consecutive frames.

    Attributes:
        dx_m: signed travel of the rear axle along its arc, metres (+ forward, - reverse).
        dtheta_rad: heading change, radians, counter-clockwise positive.
        shift_px: ``(x, y)`` floor-content shift from the previous to the current frame in the
            matching grid: image pixels (linear model) or bird's-eye cells (homography model).
        confidence: in [0, 1], from texture, blur, occlusion, match distinctiveness and range.
        stationary: the shift was below ``stationary_px`` with a good match; motion set to 0.
        sigma_xy_m: suggested standard deviation of the step's position, metres.
        sigma_theta_rad: suggested standard deviation of the heading change, radians.
        prev_T_curr: ``(x_m, y_m, yaw_rad)`` pose of the current camera-foot frame in the previous.
        model: "linear" or "homography".
    """

    dx_m: float
    dtheta_rad: float
    shift_px: tuple[float, float]
    confidence: float
    stationary: bool
    sigma_xy_m: float
    sigma_theta_rad: float
    prev_T_curr: tuple[float, float, float]
    model: str


def _arc(d_m: float, theta_rad: float, y_c_m: float) -> tuple[float, float]:
    """Camera-foot displacement (previous frame) for a rear-axle chord d at midpoint heading."""
    return (
        d_m * math.cos(theta_rad / 2) + y_c_m * (math.cos(theta_rad) - 1.0),
        d_m * math.sin(theta_rad / 2) + y_c_m * math.sin(theta_rad),
    )


def solve_arc(f1: NDArray, f2: NDArray, y_c_m: float) -> tuple[float, float]:
    """(d, theta) of the rear-axle arc taking floor point ``f2`` (current frame) to ``f1`` (previous).

    Solves ``f1 = R(theta) f2 + arc(d, theta)`` by fixed-point iteration; the lateral row is eq. 1
    with lever arm ``f2_x + y_c``, the longitudinal row is eq. 2.
    """
    (x1, y1), (x2, y2) = (float(v) for v in f1), (float(v) for v in f2)
    theta, d = 0.0, x1 - x2
    for _ in range(10):
        s = (y1 - math.cos(theta) * y2 - d * math.sin(theta / 2)) / (x2 + y_c_m)
        theta = math.asin(max(-1.0, min(1.0, s)))
        c = math.cos(theta)
        d = (x1 - c * x2 + math.sin(theta) * y2 - y_c_m * (c - 1.0)) / math.cos(theta / 2)
    return d, theta


def _rotated_grid(setup: MatchGrid, hom: NDArray, centre: NDArray, theta: float) -> NDArray[np.float64]:
    """Grid -> pixel map of a bird's-eye grid whose point g shows floor R(-theta)(g - C) + C."""
    c, s = math.cos(theta), math.sin(theta)
    rot = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    move = np.array([[1.0, 0.0, centre[0]], [0.0, 1.0, centre[1]], [0.0, 0.0, 1.0]])
    back = np.array([[1.0, 0.0, -centre[0]], [0.0, 1.0, -centre[1]], [0.0, 0.0, 1.0]])
    return np.asarray(np.linalg.inv(hom) @ move @ rot @ back @ setup.floor_from_grid)


def _energy(img: NDArray) -> NDArray[np.float32]:
    """Squared central-difference gradient magnitude, zero on the border."""
    out = np.zeros_like(img)
    out[1:-1, 1:-1] = (img[2:, 1:-1] - img[:-2, 1:-1]) ** 2 + (img[1:-1, 2:] - img[1:-1, :-2]) ** 2
    return out


def _centroid(floor_from_grid: NDArray, weights: NDArray) -> NDArray[np.float64]:
    """Floor point of the weighted centroid of a grid (geometric centroid of the support if all 0)."""
    total = float(weights.sum())
    if total <= 0:
        weights, total = (weights > 0).astype(np.float64) + 1e-12, float((weights > 0).sum()) + 1e-12
    cols, rows = grid_coords((weights.shape[1], weights.shape[0]))
    centroid = np.array([float((cols * weights).sum()), float((rows * weights).sum())]) / total
    return apply_homography(floor_from_grid, centroid)


def centre_px(rect: Rect) -> NDArray[np.float64]:
    """(2,) pixel centre (u, v) of an ``(x, y, w, h)`` rectangle."""
    return np.array([rect[0] + rect[2] / 2.0, rect[1] + rect[3] / 2.0])


def finish_step(
    d: float,
    theta: float,
    shift_px: tuple[float, float],
    confidence: float,
    camera: CameraModel,
    model: str,
    params: OdometryParams,
) -> OdometryStep:
    """The step record: stationary detection, sigmas, and the arc as a relative pose.

    ``d`` (metres) and ``theta`` (radians) are the rear axle's arc in the camera's look frame; a camera with
    ``forward_sign`` -1 looks behind, so its step is turned into the vehicle's frame here.
    """
    stationary = math.hypot(*shift_px) < params.stationary_px
    stationary = stationary and confidence >= params.stationary_min_confidence
    if stationary:
        d, theta = 0.0, 0.0
    floor = max(confidence, params.confidence_floor)
    tx, ty = _arc(d, theta, camera.y_c_m)
    if camera.forward_sign < 0:
        d, tx, ty = -d, -tx, -ty
    return OdometryStep(
        dx_m=d, dtheta_rad=theta, shift_px=shift_px, confidence=float(confidence),
        stationary=stationary, prev_T_curr=(tx, ty, theta), model=model,
        sigma_xy_m=(params.sigma_xy_base_m + params.sigma_xy_per_m * abs(d)) / floor,
        sigma_theta_rad=(params.sigma_theta_base_rad + params.sigma_theta_per_m * abs(d)) / floor,
    )  # fmt: skip


def _match_linear(
    prev: GridFrame, curr: GridFrame, camera: CameraModel, setup: MatchGrid, params: OdometryParams
) -> OdometryStep:
    """Paper model: median patch shift (x_p, y_p) -> eq. 1 and eq. 2."""
    ms = [
        register_shift(prev.pyr, curr.pyr, region, setup.valid, *setup.range_px,
                       candidates=params.coarse_candidates, radius=params.refine_radius_px, subpixel=params.subpixel)
        for region in setup.regions
    ]  # fmt: skip
    shift = (float(np.median([m.shift_px[0] for m in ms])), float(np.median([m.shift_px[1] for m in ms])))
    x_p, y_p = shift[0] / setup.scale, shift[1] / setup.scale
    d = y_p * camera.k_y_m_per_px  # along the look direction; finish_step applies forward_sign
    theta = math.atan(x_p * camera.k_x_m_per_px / (camera.y_c_m + camera.y_h_m))
    conf = min(prev.quality, curr.quality) * min(
        1.0, float(np.median([m.distinctiveness for m in ms])) / params.distinct_ref
    )
    conf *= min(1.0, min(m.overlap for m in ms) / 0.5) * (0.1 if any(m.at_range_edge for m in ms) else 1.0)
    return finish_step(d, theta, shift, conf, camera, "linear", params)


def _match_birdseye(
    prev: GridFrame,
    curr: GridFrame,
    camera: CameraModel,
    setup: MatchGrid,
    params: OdometryParams,
    prior_px: tuple[float, float] | None = None,
) -> tuple[OdometryStep, list[Pair]]:
    """Bird's-eye model; also the matched pixel pairs [ROI centre, near slice, far slice].

    ``prior_px`` (the previous step's grid shift) is one more start for the coarse search: refined
    downhill from it, it replaces the exhaustive search's pick when it ends at a lower cost (the coarse
    level can rank the true minimum below a false one: lane lines along the motion, periodic markings).
    """
    hom = camera.homography()
    assert hom is not None
    rx, ry = setup.range_px
    sub = params.subpixel
    res = -float(setup.floor_from_grid[0, 1])
    # A shift estimate is a gradient-energy weighted mean of local shifts (Lucas-Kanade), so each
    # region's correspondence sits at its texture-weighted centroid, not its geometric one.
    energy = _energy(prev.pyr[0])
    centres = [_centroid(setup.floor_from_grid, energy * region[0]) for region in setup.regions]
    centre = centres[0]

    def motion(shift_px: tuple[float, float]) -> NDArray[np.float64]:
        """Floor motion of content (look frame) for a grid shift (columns right, rows back)."""
        return -res * np.array([shift_px[1], shift_px[0]])

    def rot_w(g: NDArray, theta_w: float) -> NDArray[np.float64]:
        """Current-frame floor point shown at floor point g of the grid rotated by theta_w about C."""
        c, s = math.cos(theta_w), math.sin(theta_w)
        g = g - centre
        return np.asarray(centre + np.array([c * g[0] + s * g[1], -s * g[0] + c * g[1]]))

    def pair(shift_px: tuple[float, float], theta_w: float) -> tuple[NDArray, NDArray]:
        """Previous/current floor points of the ROI match: the two-sided cost pools the ROI in both
        frames, so the correspondence sits half a shift either side of the centroid."""
        half = 0.5 * motion(shift_px)
        return centre - half, rot_w(centre + half, theta_w)

    turned: dict[float, tuple[int, list[NDArray], list[list[NDArray]], list[NDArray]]] = {}

    def rotated(theta_w: float, levels: int) -> tuple[list[NDArray], list[list[NDArray]], list[NDArray]]:
        """Pyramids of the current frame's grid turned by theta_w about C, of its regions and valid cells
        (kept per theta_w: a pyramid's finer levels do not depend on how many coarser ones are built)."""
        if theta_w == 0.0:
            return curr.pyr[: levels + 1], [r[: levels + 1] for r in setup.regions], setup.valid[: levels + 1]
        if theta_w not in turned or turned[theta_w][0] < levels:
            m_rot = _rotated_grid(setup, hom, centre, theta_w)
            regions, valid = grid_masks(camera, setup, m_rot, max(1, params.patch_px // 2))
            pyr = normalised_pyramid(warp_to_grid(curr.raw, setup, m_rot), levels, params)
            turned[theta_w] = (
                levels,
                pyr,
                [mask_pyramid(r, levels) for r in regions],
                mask_pyramid(valid, levels),
            )
        _, pyr, regions_pyr, valid_pyr = turned[theta_w]
        return pyr[: levels + 1], [r[: levels + 1] for r in regions_pyr], valid_pyr[: levels + 1]

    def turn(shift_px: tuple[float, float], theta_w: float) -> float:
        return solve_arc(*pair(shift_px, theta_w), camera.y_c_m)[1] if params.rerotate else 0.0

    # Translation only, exhaustive at the coarsest level and refined one level down (a turn's shear
    # is still below a cell there); then the current grid is turned by the estimate and refined to
    # level 0, turned once more if the estimate moved by half a cell of shear across the footprint.
    mid = max(0, setup.levels - 1)
    prior_start = None
    if prior_px is not None and params.motion_prior:
        # The previous shift in level-``mid`` pixels, taken as a start one level coarser: twice the previous
        # motion, so the descent comes back to it from beyond (measured: a start at the previous motion
        # itself reads KITTI clip 2's turn worse, 6.5 % vs 5.4 % of the distance at the end).
        start = (round(prior_px[0] / 2**mid), round(prior_px[1] / 2**mid))
        prior_start = start if abs(start[0]) <= rx / 2**mid and abs(start[1]) <= ry / 2**mid else None
    first = register_shift(
        prev.pyr[mid:], curr.pyr[mid:], setup.regions[0][mid:], setup.valid[mid:], rx / 2**mid, ry / 2**mid,
        candidates=params.coarse_candidates, radius=params.refine_radius_px, subpixel=sub,
        also_from_px=prior_start,
    )  # fmt: skip
    shift, theta_w = (first.shift_px[0] * 2**mid, first.shift_px[1] * 2**mid), 0.0
    for i, level in enumerate((mid, 0)):
        theta = turn(shift, theta_w)
        if i == 1 and abs(theta - theta_w) * setup.extent_m < 0.5 * res:
            break
        theta_w = theta if abs(theta) > 1e-3 else 0.0
        b_pyr, b_regions, b_valid = rotated(theta_w, level)
        match = register_shift(
            prev.pyr[: level + 1], b_pyr, setup.regions[0][: level + 1], setup.valid[: level + 1], rx, ry,
            roi_b=b_regions[0], valid_b=b_valid, radius=1, subpixel=sub,
            start_px=(round(shift[0] / 2**level), round(shift[1] / 2**level)),
        )  # fmt: skip
        shift = match.shift_px
    floor_pairs = [pair(shift, theta_w)]
    if params.self_calibrate:  # one-sided slices: the correspondence lies at that frame's slice centroid
        b_pyr, b_regions, b_valid = rotated(theta_w, 0)
        b_energy = _energy(b_pyr[0])
        for k in (1, 2):
            args = (prev.pyr[:1], b_pyr, setup.regions[k][:1], setup.valid[:1], rx, ry)
            kw = {"roi_b": b_regions[k], "valid_b": b_valid, "start_px": (round(shift[0]), round(shift[1]))}
            m_a = register_shift(*args, side="a", radius=1, subpixel=sub, **kw)  # type: ignore[arg-type]
            m_b = register_shift(*args, side="b", radius=1, subpixel=sub, **kw)  # type: ignore[arg-type]
            if m_a.overlap >= m_b.overlap:  # previous slice -> anywhere in the current frame
                floor_pairs.append((centres[k], rot_w(centres[k] + motion(m_a.shift_px), theta_w)))
            else:  # current slice <- anywhere in the previous frame
                g = _centroid(setup.floor_from_grid, b_energy * b_regions[k][0])
                floor_pairs.append((g - motion(m_b.shift_px), rot_w(g, theta_w)))
    d, theta = solve_arc(*floor_pairs[0], camera.y_c_m)
    hom_inv = np.linalg.inv(hom)
    pairs: list[Pair] = [
        (apply_homography(hom_inv, f1), apply_homography(hom_inv, f2)) for f1, f2 in floor_pairs
    ]
    conf = min(prev.quality, curr.quality) * min(1.0, first.distinctiveness / params.distinct_ref)
    conf *= min(1.0, match.overlap / 0.5) * (0.1 if first.at_range_edge else 1.0)
    return finish_step(d, theta, shift, conf, camera, "homography", params), pairs


def match_step(
    prev: GridFrame,
    curr: GridFrame,
    camera: CameraModel,
    setup: MatchGrid,
    params: OdometryParams,
    prior_px: tuple[float, float] | None = None,
) -> tuple[OdometryStep, list[Pair]]:
    """The step between two prepared frames, and its matched pixels (see :class:`MatchedSteps` of
    :mod:`driftmap.core.odometry.drive`: none with the linear model).

    ``prior_px`` is the previous step's shift (grid cells), where the bird's-eye search also starts.
    """
    if setup.model == "linear":
        return _match_linear(prev, curr, camera, setup, params), []
    return _match_birdseye(prev, curr, camera, setup, params, prior_px)


def estimate_step(
    prev: NDArray, curr: NDArray, camera: CameraModel, params: OdometryParams = ODOMETRY_DEFAULT
) -> OdometryStep:
    """Vehicle motion between two consecutive frames from the floor region.

    Args:
        prev: ``(H, W)`` uint8 gray frame at time k (other real dtypes are clipped to 0-255).
        curr: ``(H, W)`` uint8 gray frame at time k + 1; ``(H, W)`` must equal the camera's size.
        camera: calibration: ROI, k_x, k_y, y_c, y_h, forward_sign, optional ground_homography.
        params: search ranges, model choice, confidence and sigma settings.

    Returns:
        :class:`OdometryStep` (metres, radians, counter-clockwise positive).

    Raises:
        BadInputError: wrong frame shapes, or a homography model without a homography.
    """
    a, b = check_frame(prev, camera, "prev"), check_frame(curr, camera, "curr")
    single = dataclasses.replace(params, self_calibrate=False)  # needs a whole drive
    setup = match_grid(camera, single)
    return match_step(
        prepare_frame(a, camera, setup, single),
        prepare_frame(b, camera, setup, single),
        camera,
        setup,
        single,
    )[0]
