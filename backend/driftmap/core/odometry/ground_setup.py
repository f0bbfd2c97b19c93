"""The ground plane of a camera from floor points seen in a frame (paper 000 III-A1: a known homography).

A technician clicks N >= 4 floor marks in one frame (pixels ``(u, v)`` of the recorded frame) and measures
their floor coordinates ``(x, y)`` in metres in the vehicle frame at the camera's foot (x forward, y left,
:class:`~driftmap.core.odometry.camera.CameraModel`). :func:`fit_ground` fits the pixel-to-floor homography
by least squares over all points (on the undistorted image when the camera has a lens) and derives the
camera block's ``k_x``, ``k_y`` and ``y_h`` at the ROI centre as :func:`~driftmap.core.odometry.drive.
shift_horizon` defines them. Points are numbered from 1 in the order given.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.lens import Lens, undistort_points
from driftmap.core.odometry.grid import Rect, apply_homography
from driftmap.core.odometry.step import centre_px
from driftmap.errors import BadInputError

__all__ = ["MIN_POINTS", "GroundFit", "fit_ground"]

MIN_POINTS = 4
_COLLINEAR = 1e-3  # a triangle is degenerate when its area is below this fraction of its longest side squared
_DUPLICATE = 1e-6  # points closer than this fraction of the spread of all points are the same point


@dataclass(frozen=True)
class GroundFit:
    """A fitted ground plane.

    Attributes:
        homography: (3, 3) map from undistorted pixel (u, v, 1) to the floor point (x, y, w), metres.
        k_x_m_per_px: floor metres per pixel step along u at the ROI centre.
        k_y_m_per_px: floor metres per pixel step along v at the ROI centre.
        y_h_m: distance from the camera's foot to the floor point at the ROI centre, metres.
        residuals_m: (N,) distance between each point's measured and fitted floor position, metres.
    """

    homography: tuple[tuple[float, float, float], ...]
    k_x_m_per_px: float
    k_y_m_per_px: float
    y_h_m: float
    residuals_m: tuple[float, ...]


def _refuse_degenerate(pts: NDArray[np.float64], space: str) -> None:
    """Refuse duplicated points, and points that leave no four in general position (collinear)."""
    n = len(pts)
    spread = float(np.ptp(pts, axis=0).max()) or 1.0
    for i, j in itertools.combinations(range(n), 2):
        if np.linalg.norm(pts[i] - pts[j]) <= _DUPLICATE * spread:
            raise BadInputError(f"points {i + 1} and {j + 1} are the same {space} point", field="points")
    lines: list[set[int]] = []
    for i, j, k in itertools.combinations(range(n), 3):
        a, b, c = pts[i], pts[j], pts[k]
        area = abs(float((b - a)[0] * (c - a)[1] - (b - a)[1] * (c - a)[0])) / 2.0
        longest = max(np.sum((b - a) ** 2), np.sum((c - a) ** 2), np.sum((c - b) ** 2))
        if area < _COLLINEAR * longest:
            merged = next((s for s in lines if len(s & {i, j, k}) >= 2), None)
            if merged is None:
                lines.append({i, j, k})
            else:
                merged |= {i, j, k}
    for line in lines:
        if n - len(line) < 2 or n == MIN_POINTS:  # four points with three on a line fix no homography
            names = ", ".join(str(p + 1) for p in sorted(line))
            raise BadInputError(
                f"points {names} are collinear {space} (a homography needs four points, no three on a line)",
                field="points",
            )


def fit_ground(pixels_px: NDArray, floor_m: NDArray, roi: Rect, lens: Lens | None = None) -> GroundFit:
    """Fit the ground homography and the camera block's scales from clicked floor points.

    Args:
        pixels_px: ``(N, 2)`` pixels ``(u, v)`` of the floor marks in the recorded frame, N >= 4.
        floor_m: ``(N, 2)`` measured floor coordinates ``(x forward, y left)``, metres, vehicle frame at
            the camera's foot.
        roi: ``(x, y, w, h)`` ground ROI of the undistorted image; the scales are taken at its centre.
        lens: the camera's lens, or None for an ideal pinhole.

    Raises:
        BadInputError: shapes that differ or fewer than 4 points, duplicated or collinear points (in the
            image or on the floor; named by number), or an ROI centre on or above the horizon.
    """
    pix = np.asarray(pixels_px, dtype=np.float64)
    floor = np.asarray(floor_m, dtype=np.float64)
    if pix.ndim != 2 or pix.shape[1] != 2 or floor.shape != pix.shape:
        raise BadInputError(
            f"need (N, 2) pixels and floor points, got {pix.shape} and {floor.shape}", field="points"
        )
    if len(pix) < MIN_POINTS:
        raise BadInputError(f"need at least {MIN_POINTS} points, found {len(pix)}", field="points")
    if not (np.all(np.isfinite(pix)) and np.all(np.isfinite(floor))):
        raise BadInputError("coordinates must be finite", field="points")
    if lens is not None:
        pix = undistort_points(lens, pix)
    _refuse_degenerate(pix, "in the image")
    _refuse_degenerate(floor, "on the floor")
    hom, _ = cv2.findHomography(pix, floor, 0)
    if hom is None:
        raise BadInputError("the points fix no homography", field="points")
    residuals = np.linalg.norm(apply_homography(hom, pix) - floor, axis=1)
    c = centre_px(roi)
    if float(hom[2] @ np.array([c[0], c[1], 1.0])) * float(hom[2] @ np.array([*pix[0], 1.0])) <= 0:
        raise BadInputError(
            f"the centre of {list(roi)} lies on or above the floor's horizon", field="ground_roi"
        )
    step_u, step_v = np.array([0.5, 0.0]), np.array([0.0, 0.5])
    f = apply_homography(hom, np.stack([c, c + step_u, c - step_u, c + step_v, c - step_v]))
    return GroundFit(
        homography=tuple((float(r[0]), float(r[1]), float(r[2])) for r in hom),
        k_x_m_per_px=float(np.linalg.norm(f[1] - f[2])),
        k_y_m_per_px=float(np.linalg.norm(f[3] - f[4])),
        y_h_m=float(np.hypot(*f[0])),
        residuals_m=tuple(float(r) for r in residuals),
    )
