"""Lens intrinsics from views of a chessboard or ChArUco board (OpenCV ``calib3d``, ``fisheye`` and ``aruco``).

A board is named by its inner-corner count ``cols x rows`` and its square side in metres; its corners lie in
the board plane at ``(i * square_m, j * square_m, 0)``, numbered row by row. A ChArUco board (a chessboard with
an ArUco marker in each white square) also names its marker side and marker dictionary; its corners are known
by number, so a view that shows only part of it still counts. Each view's corners are found in a gray image
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

__all__ = [
    "CHARUCO_DICTIONARIES",
    "MIN_CORNERS",
    "MIN_VIEWS",
    "Board",
    "BoardView",
    "LensCalibration",
    "board_points",
    "calibrate_lens",
    "find_board",
]

MIN_VIEWS = 3  # fewer views than this cannot pin down focal length, principal point and distortion
MIN_CORNERS = 8  # a ChArUco view with fewer corners than this is not used (a pose needs 4, spread out)
CHARUCO_DICTIONARIES: tuple[str, ...] = tuple(
    f"DICT_{bits}X{bits}_{count}" for bits in (4, 5, 6, 7) for count in (50, 100, 250, 1000)
)
"""The ArUco dictionaries a ChArUco board may use (OpenCV's predefined ``DICT_NxN_M``)."""


@dataclass(frozen=True)
class Board:
    """A chessboard or ChArUco target.

    Attributes:
        cols: inner corners along a row (squares per row minus one), >= 2.
        rows: inner corners along a column, >= 2.
        square_m: side of one square, metres, > 0.
        marker_m: side of a ChArUco board's markers, metres, less than ``square_m``; None: a plain chessboard.
        dictionary: a ChArUco board's marker dictionary, one of :data:`CHARUCO_DICTIONARIES` (its first
            ``(cols + 1) * (rows + 1) // 2`` markers, in OpenCV's layout).
    """

    cols: int
    rows: int
    square_m: float
    marker_m: float | None = None
    dictionary: str = "DICT_4X4_50"

    def __post_init__(self) -> None:
        if self.cols < 2 or self.rows < 2:
            raise BadInputError(
                f"needs at least 2x2 inner corners, found {self.cols}x{self.rows}", field="board"
            )
        if not self.square_m > 0:
            raise BadInputError(f"must be positive, found {self.square_m}", field="square_m")
        if self.marker_m is None:
            return
        if not 0 < self.marker_m < self.square_m:
            raise BadInputError(
                f"must be positive and less than the square side {self.square_m}, found {self.marker_m}",
                field="marker_m",
            )
        if self.dictionary not in CHARUCO_DICTIONARIES:
            raise BadInputError(
                f"must be one of {', '.join(CHARUCO_DICTIONARIES)}, found {self.dictionary!r}",
                field="dictionary",
            )
        markers = (self.cols + 1) * (self.rows + 1) // 2
        if markers > int(self.dictionary.rsplit("_", 1)[1]):
            raise BadInputError(
                f"{self.dictionary} has too few markers for a board of {self.cols + 1}x{self.rows + 1} "
                f"squares ({markers} needed)",
                field="dictionary",
            )

    @property
    def is_charuco(self) -> bool:
        """Whether the board carries ArUco markers (its corners are found by number)."""
        return self.marker_m is not None

    def describe(self) -> str:
        """The board as a user names it, e.g. ``9x6`` or ``9x6 ChArUco``."""
        return f"{self.cols}x{self.rows}{' ChArUco' if self.is_charuco else ''}"


@dataclass(frozen=True)
class BoardView:
    """The corners of a board found in one image.

    Attributes:
        ids: ``(N,)`` int64 corner numbers into :func:`board_points` (all of them, in order, for a chessboard).
        pixels: ``(N, 2)`` float64 sub-pixel corners ``(u, v)``, pixels.
    """

    ids: NDArray[np.int64]
    pixels: NDArray[np.float64]


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


def find_board(image: NDArray, board: Board) -> BoardView | None:
    """The board's inner corners in a gray image, or None when the board is not seen.

    A chessboard must be seen whole: its ``cols * rows`` corners come in the order of :func:`board_points`
    (up to the board's symmetry). A ChArUco board's corners come with their numbers; a view with fewer than
    :data:`MIN_CORNERS` of them counts as not seen.

    Args:
        image: ``(H, W)`` uint8 gray image.
        board: the target.
    """
    gray = np.asarray(image)
    if gray.ndim != 2:
        raise BadInputError(f"must be a gray (H, W) image, got shape {gray.shape}", field="image")
    gray = gray if gray.dtype == np.uint8 else np.clip(gray, 0, 255).astype(np.uint8)
    if board.is_charuco:
        return _find_charuco(gray, board)
    size = (board.cols, board.rows)
    found, corners = cv2.findChessboardCornersSB(gray, size, flags=cv2.CALIB_CB_NORMALIZE_IMAGE)
    if not found:
        flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
        found, corners = cv2.findChessboardCorners(gray, size, flags=flags)
        if not found:
            return None
        crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 0.01)
        corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), crit)
    pixels = np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    return BoardView(np.arange(len(pixels), dtype=np.int64), pixels)


def _charuco_board(board: Board) -> cv2.aruco.CharucoBoard:
    """OpenCV's board of ``(cols + 1) x (rows + 1)`` squares (corner k of it is corner k of ours)."""
    assert board.marker_m is not None
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, board.dictionary))
    return cv2.aruco.CharucoBoard(
        (board.cols + 1, board.rows + 1), board.square_m, board.marker_m, dictionary
    )


def _find_charuco(gray: NDArray[np.uint8], board: Board) -> BoardView | None:
    """The numbered ChArUco corners of a ``(H, W)`` uint8 image, or None with fewer than MIN_CORNERS."""
    detector = cv2.aruco.CharucoDetector(_charuco_board(board))
    corners, ids, _, _ = detector.detectBoard(gray)
    if corners is None or ids is None or len(ids) < MIN_CORNERS:
        return None
    return BoardView(
        np.asarray(ids, dtype=np.int64).ravel(), np.asarray(corners, dtype=np.float64).reshape(-1, 2)
    )


def calibrate_lens(
    views: Sequence[BoardView], board: Board, size: tuple[int, int], model: LensModel = "pinhole"
) -> LensCalibration:
    """Fit a lens to the corners of several views of one board.

    Args:
        views: the corners :func:`find_board` found in each view.
        board: the target seen in every view.
        size: ``(width, height)`` of the images, pixels.
        model: ``"pinhole"`` (k1 k2 p1 p2 k3) or ``"fisheye"`` (k1..k4).

    Raises:
        BadInputError: fewer than :data:`MIN_VIEWS` views (field ``images``), a view with fewer than 4
            corners or corner numbers the board does not have, an unknown model, or a calibration that
            does not converge.
    """
    if model not in LENS_MODELS:
        raise BadInputError(f"must be one of {', '.join(LENS_MODELS)}, found {model!r}", field="model")
    if len(views) < MIN_VIEWS:
        raise BadInputError(
            f"the board was found in {len(views)} view(s); calibration needs at least {MIN_VIEWS}",
            field="images",
        )
    corners = board_points(board)
    objs: list[NDArray[np.float64]] = []
    pts: list[NDArray[np.float64]] = []
    for index, view in enumerate(views):
        ids = np.asarray(view.ids, dtype=np.int64).ravel()
        p = np.asarray(view.pixels, dtype=np.float64).reshape(-1, 2)
        if len(ids) != len(p) or len(p) < 4 or ids.min() < 0 or ids.max() >= len(corners):
            numbers = f" numbered {ids.min()}..{ids.max()}" if len(ids) else ""
            raise BadInputError(
                f"view {index + 1} has {len(p)} corners{numbers}; needs at least 4 of the board's "
                f"{len(corners)}, numbered 0..{len(corners) - 1}",
                field="images",
            )
        objs.append(corners[ids])
        pts.append(p)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-9)
    try:
        if model == "fisheye":
            flags = cv2.fisheye.CALIB_RECOMPUTE_EXTRINSIC | cv2.fisheye.CALIB_FIX_SKEW
            _, k, d, rvecs, tvecs = cv2.fisheye.calibrate(
                [o.reshape(-1, 1, 3) for o in objs], [p.reshape(-1, 1, 2) for p in pts], size, np.eye(3), np.zeros(4),
                flags=flags, criteria=crit,
            )  # fmt: skip
        else:
            _, k, d, rvecs, tvecs = cv2.calibrateCamera(
                [o.astype(np.float32) for o in objs], [p.astype(np.float32) for p in pts], size, None, None,
                criteria=crit,
            )  # fmt: skip
    except cv2.error as exc:
        raise BadInputError(f"calibration did not converge: {exc.err}", field="images") from None
    coeffs = np.asarray(d, dtype=np.float64).ravel()[: 4 if model == "fisheye" else 5]
    mat = np.asarray(k, dtype=np.float64)
    lens = Lens(model, tuple((float(r[0]), float(r[1]), float(r[2])) for r in mat), tuple(map(float, coeffs)))
    errors = []
    for obj, p, rvec, tvec in zip(objs, pts, rvecs, tvecs, strict=True):
        if model == "fisheye":
            proj, _ = cv2.fisheye.projectPoints(
                obj.reshape(-1, 1, 3), rvec, tvec, lens.matrix(), lens.coeffs()
            )
        else:
            proj, _ = cv2.projectPoints(obj, rvec, tvec, lens.matrix(), lens.coeffs())
        errors.append(np.sum((np.asarray(proj).reshape(-1, 2) - p) ** 2, axis=1))
    view_rms = tuple(float(np.sqrt(e.mean())) for e in errors)
    return LensCalibration(lens, float(np.sqrt(np.concatenate(errors).mean())), view_rms)
