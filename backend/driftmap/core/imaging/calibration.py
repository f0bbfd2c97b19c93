"""Lens intrinsics from views of a chessboard (OpenCV ``calib3d`` and ``fisheye`` calibration).

A board is named by its inner-corner count ``cols x rows`` and its square side in metres; its corners lie in
the board plane at ``(i * square_m, j * square_m, 0)``. Each view's corners are found in a gray image
(:func:`find_board`), then all views are calibrated together (:func:`calibrate_lens`), which reports the
reprojection RMS of each view in pixels.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.lens import LENS_MODELS, Lens, LensModel
from driftmap.errors import BadInputError

__all__ = ["MIN_VIEWS", "Board", "LensCalibration", "board_points", "calibrate_lens", "find_board"]

MIN_VIEWS = 3  # fewer views than this cannot pin down focal length, principal point and distortion


@dataclass(frozen=True)
class Board:
    """A chessboard target.

    Attributes:
        cols: inner corners along a row (squares per row minus one), >= 2.
        rows: inner corners along a column, >= 2.
        square_m: side of one square, metres, > 0.
    """

    cols: int
    rows: int
    square_m: float

    def __post_init__(self) -> None:
        if self.cols < 2 or self.rows < 2:
            raise BadInputError(
                f"needs at least 2x2 inner corners, found {self.cols}x{self.rows}", field="board"
            )
        if not self.square_m > 0:
            raise BadInputError(f"must be positive, found {self.square_m}", field="square_m")


@dataclass(frozen=True)
class LensCalibration:
    """The result of a calibration.

    Attributes:
        lens: the fitted lens (``K`` in pixels).
        rms_px: reprojection RMS over all corners of all views, pixels.
        view_rms_px: reprojection RMS of each view, pixels, in the order given.
    """

    lens: Lens
    rms_px: float
    view_rms_px: tuple[float, ...]


def board_points(board: Board) -> NDArray[np.float64]:
    """``(cols * rows, 3)`` float64 corners in the board plane, metres, row by row (x fastest)."""
    jj, ii = np.mgrid[0 : board.rows, 0 : board.cols]
    pts = np.stack([ii.ravel(), jj.ravel(), np.zeros(ii.size)], axis=1)
    return np.asarray(pts * board.square_m, dtype=np.float64)


def find_board(image: NDArray, board: Board) -> NDArray[np.float64] | None:
    """The board's inner corners in a gray image, or None when the board is not (wholly) seen.

    Args:
        image: ``(H, W)`` uint8 gray image.
        board: the target.

    Returns:
        ``(cols * rows, 2)`` float64 sub-pixel corners ``(u, v)``, in the order of :func:`board_points`
        (up to the board's symmetry), or None.
    """
    gray = np.asarray(image)
    if gray.ndim != 2:
        raise BadInputError(f"must be a gray (H, W) image, got shape {gray.shape}", field="image")
    gray = gray if gray.dtype == np.uint8 else np.clip(gray, 0, 255).astype(np.uint8)
    size = (board.cols, board.rows)
    found, corners = cv2.findChessboardCornersSB(gray, size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not found:
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        found, corners = cv2.findChessboardCorners(gray, size, flags=flags)
        if not found:
            return None
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 0.01)
        corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), crit)
    return np.asarray(corners, dtype=np.float64).reshape(-1, 2)


def calibrate_lens(
    views: Sequence[NDArray], board: Board, size: tuple[int, int], model: LensModel = "pinhole"
) -> LensCalibration:
    """Fit a lens to the corners of several views of one board.

    Args:
        views: per view, ``(cols * rows, 2)`` corner pixels from :func:`find_board`.
        board: the target seen in every view.
        size: ``(width, height)`` of the images, pixels.
        model: ``"pinhole"`` (k1 k2 p1 p2 k3) or ``"fisheye"`` (k1..k4).

    Raises:
        BadInputError: fewer than :data:`MIN_VIEWS` views (field ``images``), a view of the wrong corner
            count, an unknown model, or a calibration that does not converge.
    """
    if model not in LENS_MODELS:
        raise BadInputError(f"must be one of {', '.join(LENS_MODELS)}, found {model!r}", field="model")
    if len(views) < MIN_VIEWS:
        raise BadInputError(
            f"the board was found in {len(views)} view(s); calibration needs at least {MIN_VIEWS}",
            field="images",
        )
    obj = board_points(board)
    pts = [np.asarray(v, dtype=np.float64).reshape(-1, 2) for v in views]
    for index, p in enumerate(pts):
        if p.shape != (len(obj), 2):
            raise BadInputError(
                f"view {index + 1} has {p.shape[0]} corners, the board {len(obj)}", field="images"
            )
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-9)
    try:
        if model == "fisheye":
            flags = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
            _, k, d, rvecs, tvecs = cv2.fisheye.calibrate(
                [obj.reshape(-1, 1, 3) for _ in pts], [p.reshape(-1, 1, 2) for p in pts], size, np.eye(3), np.zeros(4),
                flags=flags, criteria=crit,
            )  # fmt: skip
        else:
            _, k, d, rvecs, tvecs = cv2.calibrateCamera(
                [obj.astype(np.float32)] * len(pts), [p.astype(np.float32) for p in pts], size, None, None,
                criteria=crit,
            )  # fmt: skip
    except cv2.error as exc:
        raise BadInputError(f"calibration did not converge: {exc.err}", field="images") from None
    coeffs = np.asarray(d, dtype=np.float64).ravel()[: 4 if model == "fisheye" else 5]
    mat = np.asarray(k, dtype=np.float64)
    lens = Lens(model, tuple((float(r[0]), float(r[1]), float(r[2])) for r in mat), tuple(map(float, coeffs)))
    errors = []
    for p, rvec, tvec in zip(pts, rvecs, tvecs, strict=True):
        if model == "fisheye":
            proj, _ = cv2.fisheye.projectPoints(
                obj.reshape(-1, 1, 3), rvec, tvec, lens.matrix(), lens.coeffs()
            )
        else:
            proj, _ = cv2.projectPoints(obj, rvec, tvec, lens.matrix(), lens.coeffs())
        errors.append(np.sum((np.asarray(proj).reshape(-1, 2) - p) ** 2, axis=1))
    view_rms = tuple(float(np.sqrt(e.mean())) for e in errors)
    return LensCalibration(lens, float(np.sqrt(np.concatenate(errors).mean())), view_rms)
