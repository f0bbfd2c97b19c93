"""Camera calibration: lens intrinsics from chessboard or ChArUco views, the ground plane from floor points.

Every function takes plain data (decoded images, point arrays, a camera block as a JSON object) and returns a
result value, so ``driftmap camera`` and ``/api/cameras`` calibrate identically. Errors are
:class:`~driftmap.errors.BadInputError` naming the field at fault (``images``, ``video``, ``points``,
``ground_roi``, ``lens``, ...); the callers pass the field names their users typed.

A camera block in progress is a ``camera`` block of ``docs/formats.md`` that may lack keys:
:func:`add_lens` and :func:`add_ground` merge a calibration into one.
"""

from __future__ import annotations

import re
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, cast

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.calibration import Board, BoardView, calibrate_lens, find_board
from driftmap.core.imaging.lens import LENS_MODELS, Lens, LensModel
from driftmap.core.odometry.grid import Rect
from driftmap.core.odometry.ground_setup import GroundFit, board_floor_points, fit_ground
from driftmap.errors import BadInputError, PayloadTooLargeError
from driftmap.formats.drive_json import lens_to_json, parse_lens_block
from driftmap.formats.frame_images import check_frame_pixels, decode_gray

__all__ = [
    "FITTED_GROUND",
    "Ground",
    "Intrinsics",
    "add_ground",
    "add_lens",
    "board_ground_points",
    "calibrate_intrinsics",
    "choose_roi",
    "decode_images",
    "fit_ground_points",
    "parse_board",
    "parse_lens",
]

FITTED_GROUND: tuple[str, ...] = ("k_x", "k_y", "y_h", "ground_homography")
"""Keys fitted on the undistorted image of one lens: a new lens makes them stale."""
_BOARD_RE = re.compile(r"^\s*(\d+)\s*[xX]\s*(\d+)\s*$")


def parse_board(
    text: str,
    square_m: float,
    field: str = "board",
    *,
    marker_m: float | None = None,
    dictionary: str | None = None,
) -> Board:
    """The board ``COLSxROWS`` (inner corners, e.g. ``9x6``) with squares of ``square_m`` metres; a ChArUco
    board when ``marker_m`` (its markers' side, metres) is given, of ``dictionary`` (default ``DICT_4X4_50``).

    Raises:
        BadInputError: a malformed ``text`` (``field``), a bad square or marker side, an unknown dictionary or
            one with too few markers, or a dictionary without a marker side (``marker_m``).
    """
    match = _BOARD_RE.match(text)
    if match is None:
        raise BadInputError(f"must be COLSxROWS inner corners, e.g. 9x6, found {text!r}", field=field)
    if dictionary is not None and marker_m is None:
        raise BadInputError("a ChArUco dictionary needs the markers' side too", field="marker_m")
    extra = {"dictionary": dictionary} if dictionary is not None else {}
    return Board(int(match.group(1)), int(match.group(2)), square_m, marker_m, **extra)


def parse_lens(lens: object, field: str = "lens") -> Lens:
    """Validate a ``lens`` object of a camera block given on its own (errors name ``<field>.<key>``)."""
    try:
        return parse_lens_block(lens, "", "request body")
    except BadInputError as exc:
        name = (exc.field or "camera.lens").replace("camera.lens", field, 1)
        raise BadInputError(exc.reason, field=name) from None


def decode_images(
    files: Iterable[tuple[str, bytes]], field: str = "images", max_pixels: int | None = None
) -> Iterator[tuple[str, NDArray[np.uint8]]]:
    """Decode uploaded board images ``(name, PNG or JPEG bytes)`` to ``(name, (H, W) uint8)``, one at a time.

    Raises:
        BadInputError: a file that is not a PNG or JPEG image (naming the file and ``field``).
        PayloadTooLargeError: an image whose header declares more than ``max_pixels`` pixels (not decoded).
    """
    for name, data in files:
        try:
            if max_pixels is not None:
                check_frame_pixels(data, name, max_pixels, field)
            image = decode_gray(data, name)
        except BadInputError as exc:
            raise type(exc)(exc.reason, file=name, field=field) from None
        yield name, image


@dataclass(frozen=True)
class Intrinsics:
    """A calibrated lens and how well each view fits it.

    Attributes:
        lens: the fitted lens (K in pixels of the calibrated images).
        width_px: width of the images, pixels.
        height_px: height of the images, pixels.
        rms_px: reprojection RMS over every view, pixels.
        views: ``(name, RMS px)`` of each view the board was found in, in input order.
        skipped: names of the images the board was not found in.
    """

    lens: Lens
    width_px: int
    height_px: int
    rms_px: float
    views: tuple[tuple[str, float], ...]
    skipped: tuple[str, ...]


def calibrate_intrinsics(
    images: Iterable[tuple[str, NDArray[np.uint8]]],
    board: Board,
    model: str,
    field: str = "images",
    max_pixels: int | None = None,
) -> Intrinsics:
    """Find ``board`` in each ``(name, (H, W) uint8)`` image and fit a ``model`` lens to every view found.

    Raises:
        PayloadTooLargeError: an image of more than ``max_pixels`` pixels (a video's frames are checked here).
        BadInputError: an unknown model (field ``model``); no images, images of different sizes or fewer
            views with the board than calibration needs (``field``, with the skipped names).
    """
    if model not in LENS_MODELS:
        raise BadInputError(f"must be one of {', '.join(LENS_MODELS)}, found {model!r}", field="model")
    names: list[str] = []
    views: list[BoardView] = []
    skipped: list[str] = []
    size: tuple[int, int] | None = None
    for name, image in images:
        shape = (int(image.shape[1]), int(image.shape[0]))
        if max_pixels is not None and shape[0] * shape[1] > max_pixels:
            raise PayloadTooLargeError(
                f"image of {shape[0]}x{shape[1]} pixels is over the {max_pixels} pixel limit",
                file=name,
                field=field,
            )
        if size is not None and shape != size:
            raise BadInputError(
                f"is {shape[0]}x{shape[1]}, the first image {size[0]}x{size[1]}", file=name, field=field
            )
        size = shape
        view = find_board(image, board)
        if view is None:
            skipped.append(name)
            continue
        names.append(name)
        views.append(view)
    if size is None:
        raise BadInputError("no images given", field=field)
    try:
        result = calibrate_lens(views, board, size, cast(LensModel, model))
    except BadInputError as exc:
        missing = f" (no {board.describe()} board in: {', '.join(skipped)})" if skipped else ""
        raise BadInputError(exc.reason + missing, field=field) from None
    return Intrinsics(
        result.lens,
        size[0],
        size[1],
        float(result.rms_px),
        tuple(zip(names, (float(r) for r in result.view_rms_px), strict=True)),
        tuple(skipped),
    )


def add_lens(
    block: dict[str, Any], found: Intrinsics, file: str = "camera"
) -> tuple[dict[str, Any], list[str]]:
    """A camera block in progress with ``found``'s lens and frame size, and the fitted keys it dropped.

    The ground keys (:data:`FITTED_GROUND`) refer to the undistorted image of the old lens, so a different
    lens drops them (run the ground calibration again); ``ground_roi`` and the mounting stay.

    Raises:
        BadInputError: the block's frame size differs from the images' (field ``camera.width``).
    """
    size = (found.width_px, found.height_px)
    if (block.get("width"), block.get("height")) not in ((None, None), size):
        raise BadInputError(
            f"says {block.get('width')}x{block.get('height')} but the images are {size[0]}x{size[1]}",
            file=file,
            field="camera.width",
        )
    out = dict(block)
    lens = lens_to_json(found.lens)
    stale = [k for k in FITTED_GROUND if k in out] if out.get("lens") != lens else []
    for key in stale:
        del out[key]
    out.update({"width": size[0], "height": size[1], "lens": lens})
    return out, stale


@dataclass(frozen=True)
class Ground:
    """A fitted ground plane and the ROI its scales were taken at.

    Attributes:
        roi: ``(x, y, w, h)`` ground ROI of the undistorted image, pixels.
        fit: the homography, ``k_x``, ``k_y`` (m/px), ``y_h`` (m) and each point's residual (m).
    """

    roi: Rect
    fit: GroundFit

    def block_values(self) -> dict[str, Any]:
        """The camera block keys this fit sets: ``ground_roi``, ``k_x``, ``k_y``, ``y_h``,
        ``ground_homography`` (3x3 nested list)."""
        return {
            "ground_roi": [int(v) for v in self.roi],
            "k_x": float(self.fit.k_x_m_per_px),
            "k_y": float(self.fit.k_y_m_per_px),
            "y_h": float(self.fit.y_h_m),
            "ground_homography": [[float(v) for v in row] for row in self.fit.homography],
        }


def choose_roi(
    roi: Sequence[int] | None,
    width: int,
    height: int,
    pixels_px: NDArray[np.float64],
    field: str = "ground_roi",
) -> Rect:
    """The ground ROI ``(x, y, w, h)``: ``roi`` when given, else the bounding box of the ``(N, 2)`` pixels.

    Raises:
        BadInputError: an ROI that is not 4 integers lying inside the ``width`` x ``height`` frame.
    """
    if roi is not None:
        if len(roi) != 4:
            raise BadInputError(f"must be [x, y, w, h], found {list(roi)!r}", field=field)
        x, y, w, h = (int(v) for v in roi)
    else:
        lo, hi = np.min(pixels_px, axis=0), np.max(pixels_px, axis=0)
        x, y = max(int(lo[0]), 0), max(int(lo[1]), 0)
        w = min(int(hi[0]) + 1, width) - x
        h = min(int(hi[1]) + 1, height) - y
    if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > width or y + h > height:
        raise BadInputError(
            f"[{x}, {y}, {w}, {h}] does not lie inside the {width}x{height} frame", field=field
        )
    return (x, y, w, h)


def fit_ground_points(
    pixels_px: NDArray[np.float64],
    floor_m: NDArray[np.float64],
    width: int,
    height: int,
    roi: Sequence[int] | None = None,
    lens: Lens | None = None,
    roi_field: str = "ground_roi",
) -> Ground:
    """Fit the ground plane to clicked floor points.

    Args:
        pixels_px: ``(N, 2)`` raw pixels ``(u, v)`` of the floor marks, N >= 4.
        floor_m: ``(N, 2)`` their floor positions ``(x, y)``, metres, look frame (x the way the camera looks, y
            to its left, origin on the floor under the camera).
        width: frame width, pixels.
        height: frame height, pixels.
        roi: ``(x, y, w, h)`` ground ROI of the undistorted image; None: the points' bounding box.
        lens: the camera's lens (clicked pixels are undistorted first), or None.
        roi_field: the field name of the ROI in errors.

    Raises:
        BadInputError: fewer than 4 points, duplicated or collinear points (field ``points``, the points
            named by number from 1), or an ROI outside the frame or above the horizon.
    """
    pixels = np.asarray(pixels_px, dtype=np.float64).reshape(-1, 2)
    floor = np.asarray(floor_m, dtype=np.float64).reshape(-1, 2)
    if len(pixels) == 0:
        raise BadInputError("no floor points given: at least 4 are needed", field="points")
    rect = choose_roi(roi, width, height, pixels, roi_field)
    return Ground(rect, fit_ground(pixels, floor, rect, lens))


def board_ground_points(
    image: NDArray[np.uint8],
    name: str,
    board: Board,
    centre_m: tuple[float, float],
    yaw_rad: float,
    lens: Lens | None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The inner corners of a board lying on the floor in one ``(H, W)`` uint8 frame, as floor points.

    Returns:
        ``(N, 2)`` corner pixels and ``(N, 2)`` floor positions, metres (board centre at ``centre_m``, its
        rows pointing at ``yaw_rad``).

    Raises:
        BadInputError: no board found in the frame, or a board an upright camera cannot see (naming ``name``).
    """
    if board.is_charuco:
        raise BadInputError("a board on the floor must be a plain chessboard", field="board")
    view = find_board(image, board)
    if view is None:
        raise BadInputError(f"no {board.describe()} board found", file=name)
    try:
        floor = board_floor_points(view.pixels, board, centre_m, yaw_rad, lens)
    except BadInputError as exc:
        raise BadInputError(exc.reason, file=name, field=exc.field) from None
    return view.pixels, floor


def add_ground(
    block: dict[str, Any], ground: Ground, y_c_m: float | None = None, forward_sign: int | None = None
) -> dict[str, Any]:
    """A camera block in progress with ``ground``'s keys and the mounting (``y_c`` metres, ``forward_sign``);
    a mounting value not given keeps the block's, else ``y_c`` 0 and ``forward_sign`` 1."""
    out = {**block, **ground.block_values()}
    out["y_c"] = y_c_m if y_c_m is not None else out.get("y_c", 0.0)
    out["forward_sign"] = forward_sign if forward_sign is not None else out.get("forward_sign", 1)
    return out
