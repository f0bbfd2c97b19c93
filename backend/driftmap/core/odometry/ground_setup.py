"""The ground plane of a camera from floor points seen in a frame ([SSLAM] III-A1: a known homography).

A technician clicks N >= 4 floor marks in one frame (pixels ``(u, v)`` of the recorded frame) and measures
their floor coordinates ``(x, y)`` in metres in the camera's look frame at its foot (x the way it looks, y left,
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

from driftmap.core.imaging.calibration import Board
from driftmap.core.imaging.lens import Lens, undistort_points
from driftmap.core.odometry.grid import Rect, apply_homography
from driftmap.core.odometry.step import centre_px
from driftmap.errors import BadInputError

__all__ = ["MIN_POINTS", "GroundFit", "board_floor_points", "fit_ground"]

MIN_POINTS = 4
_COLLINEAR = 1e-3  # a triangle is degenerate when its area is below this fraction of its longest side squared
_DUPLICATE = 1e-6  # points closer than this fraction of the spread of all points are the same point


@dataclass(frozen=True)
class GroundFit:
    """A fitted ground plane.

    Attributes:
        homography: (3, 3) map from undistorted pixel (u, v, 1) to the floor point (x, y, w), metres; w > 0
            on the floor.
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
        floor_m: ``(N, 2)`` measured floor coordinates ``(x, y)``, metres, look frame (x the way the camera looks) at
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
    if float(hom[2] @ np.array([*pix.mean(axis=0), 1.0])) < 0:
        hom = -hom  # the scale OpenCV picks (h33 = 1) may be negative; floor points have w > 0
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


def board_floor_points(
    corners_px: NDArray, board: Board, centre_m: tuple[float, float], yaw_rad: float, lens: Lens | None = None
) -> NDArray[np.float64]:
    """Floor positions of the inner corners of a chessboard lying flat on the floor.

    The board's centre lies at ``centre_m`` (x the way the camera looks, y left, metres, at the camera's foot)
    and its rows (the ``cols`` direction) point at ``yaw_rad`` counter-clockwise from x. A detector
    may number the corners from either end, so of the four numberings (turned half a turn, mirrored) the one
    is kept that an upright camera looking at the floor can see: image content higher up is farther away,
    and the image is not mirrored (pixel-to-floor Jacobian with a negative determinant).

    Args:
        corners_px: ``(cols * rows, 2)`` corner pixels of the recorded frame, row by row as detected.
        board: the board (``cols != rows``, so rows and columns cannot be confused).
        centre_m: floor position of the board's centre, metres.
        yaw_rad: direction of the board's rows, radians.
        lens: the camera's lens, or None.

    Returns:
        ``(cols * rows, 2)`` float64 floor points, metres, in the order of ``corners_px``.

    Raises:
        BadInputError: a square board, a wrong corner count, or no numbering an upright camera could see.
    """
    n = board.cols * board.rows
    pix = np.asarray(corners_px, dtype=np.float64)
    if pix.shape != (n, 2):
        raise BadInputError(
            f"need {n} corners of a {board.cols}x{board.rows} board, got {pix.shape}", field="board"
        )
    if board.cols == board.rows:
        raise BadInputError(
            "a board on the floor needs COLS != ROWS (its rows must be told apart)", field="board"
        )
    ideal = undistort_points(lens, pix) if lens is not None else pix
    jj, ii = np.divmod(np.arange(n), board.cols)
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    numberings = [
        (ii, jj),
        (board.cols - 1 - ii, board.rows - 1 - jj),
        (ii, board.rows - 1 - jj),
        (board.cols - 1 - ii, jj),
    ]
    centre_px = ideal.mean(axis=0)
    probe = centre_px + np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [0.0, -10.0], [0.0, 10.0]])
    seen = []
    for i, j in numberings:
        off = np.stack([(i - (board.cols - 1) / 2), (j - (board.rows - 1) / 2)], axis=1) * board.square_m
        floor = np.asarray(centre_m) + off @ np.array([[c, s], [-s, c]])
        hom, _ = cv2.findHomography(ideal, floor, 0)
        if hom is None:
            continue
        f = apply_homography(hom, probe)
        jac = np.stack([f[1] - f[0], f[2] - f[0]], axis=1)
        if np.linalg.det(jac) < 0 and np.linalg.norm(f[3]) > np.linalg.norm(f[4]):
            seen.append(floor)
    if len(seen) != 1:
        raise BadInputError(
            "the board's corners fit no view of an upright camera looking at the floor", field="board"
        )
    return np.asarray(seen[0], dtype=np.float64)
