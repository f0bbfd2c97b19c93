"""The bird's-eye view of the floor around a camera's ground ROI, for a person checking a ground fit.

A camera's ``ground_homography`` maps a pixel ``(u, v, 1)`` of its undistorted image to the floor point
``(x, y, w)`` in its *look frame*: origin on the floor under the camera, x along the floor the way the camera
looks, y to its left, metres, ``w > 0`` on the floor in view (``docs/formats.md``). :func:`birdseye_view`
resamples the undistorted image onto a metric grid around the ROI's *footprint* (the floor quadrilateral the
ROI sees): square cells of ``res_m_per_px``, x pointing up the image and y to the left, the orientation of
odometry's bird's-eye grid (:mod:`driftmap.core.odometry.grid`). A floor pattern of known size shows at its
size; a homography that is off shows as stretched, sheared or curved floor lines.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.odometry.grid import Rect, apply_homography
from driftmap.errors import BadInputError

__all__ = ["MAX_VIEW_PX", "BirdsEye", "birdseye_view", "roi_footprint"]

MAX_VIEW_PX = 400
"""Default longer side of a bird's-eye view, pixels."""
_MAX_COND = 1e12  # a homography whose condition number is above this is taken as singular


@dataclass(frozen=True)
class BirdsEye:
    """A bird's-eye view of the floor.

    Attributes:
        image: ``(h, w)`` uint8 floor image; cells the camera does not see (outside the undistorted image,
            or behind the camera's horizon) are 0.
        floor_from_px: ``(3, 3)`` float64 map from a view pixel ``(col, row, 1)`` (pixel centres at integers)
            to the floor point ``(x, y, 1)``, look frame, metres: ``x = x_top - res * row``,
            ``y = y_left - res * col``.
        res_m_per_px: side of one view pixel on the floor, metres (a whole number of millimetres).
        footprint_m: ``(4, 2)`` float64 floor points ``(x, y)`` of the ROI's corners (top-left, top-right,
            bottom-right, bottom-left in the image), look frame, metres.
        footprint_px: ``(4, 2)`` float64 the same corners in view pixels ``(col, row)``.
    """

    image: NDArray[np.uint8]
    floor_from_px: NDArray[np.float64]
    res_m_per_px: float
    footprint_m: NDArray[np.float64]
    footprint_px: NDArray[np.float64]

    def ranges_m(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """``((x_min, x_max), (y_min, y_max))``: the floor the view covers to its pixels' outer edges, metres."""
        height, width = self.image.shape
        x_top, y_left, res = self.floor_from_px[0, 2], self.floor_from_px[1, 2], self.res_m_per_px
        x_range = (float(x_top - (height - 0.5) * res), float(x_top + 0.5 * res))
        y_range = (float(y_left - (width - 0.5) * res), float(y_left + 0.5 * res))
        return x_range, y_range


def _check_homography(hom: NDArray) -> NDArray[np.float64]:
    h = np.asarray(hom, dtype=np.float64)
    if h.shape != (3, 3) or not np.all(np.isfinite(h)):
        raise BadInputError(
            f"must be a 3x3 matrix of finite numbers, got shape {h.shape}", field="ground_homography"
        )
    if not np.linalg.cond(h) < _MAX_COND:
        raise BadInputError(
            "is singular: it maps the image onto a line or a point", field="ground_homography"
        )
    return h


def roi_footprint(hom: NDArray, roi: Rect) -> NDArray[np.float64]:
    """The floor quadrilateral a ground ROI sees.

    Args:
        hom: ``(3, 3)`` ground homography, undistorted pixel ``(u, v, 1)`` -> floor ``(x, y, w)``, look frame.
        roi: ``(x, y, w, h)`` ground ROI of the undistorted image, pixels.

    Returns:
        ``(4, 2)`` float64 floor points ``(x, y)``, metres, of the ROI's top-left, top-right, bottom-right and
        bottom-left corners (a homography maps the ROI's straight sides to the quadrilateral's).

    Raises:
        BadInputError: a corner at or above the homography's horizon (``w <= 0``; field ``ground_roi``), or a
            homography that is not a finite invertible 3x3 matrix (field ``ground_homography``).
    """
    h = _check_homography(hom)
    x, y, w, hgt = roi
    corners = np.array([[x, y], [x + w, y], [x + w, y + hgt], [x, y + hgt]], dtype=np.float64)
    if np.any(corners @ h[2, :2] + h[2, 2] <= 0):
        raise BadInputError("reaches above the horizon of ground_homography", field="ground_roi")
    return apply_homography(h, corners)


def birdseye_view(
    image: NDArray[np.uint8], hom: NDArray, roi: Rect, max_px: int = MAX_VIEW_PX, margin: float = 0.25
) -> BirdsEye:
    """Resample an undistorted image onto a metric floor grid around the ground ROI's footprint.

    Args:
        image: ``(H, W)`` uint8 undistorted image (the frame itself for a camera without a lens).
        hom: ``(3, 3)`` ground homography of that image, pixel -> floor ``(x, y, w)``, look frame, metres.
        roi: ``(x, y, w, h)`` ground ROI, pixels, inside the image.
        max_px: longer side of the view, pixels; the resolution is the footprint's padded extent over this,
            rounded up to a whole millimetre.
        margin: floor shown around the footprint's bounding box on each side, as a fraction of its longer side.

    Returns:
        The :class:`BirdsEye` view: x up the image, y to the left.

    Raises:
        BadInputError: an image that is not ``(H, W)`` uint8 (field ``frame``), an ROI outside it or above
            the horizon (``ground_roi``), a homography that is not finite and invertible (``ground_homography``).
    """
    if image.ndim != 2 or image.dtype != np.uint8:
        raise BadInputError(
            f"must be a grey (H, W) uint8 image, got {image.shape} {image.dtype}", field="frame"
        )
    if max_px < 8 or not margin >= 0:
        raise BadInputError(f"max_px must be >= 8 and margin >= 0, got {max_px}, {margin}", field="max_px")
    height, width = image.shape
    x, y, w, h = roi
    if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > width or y + h > height:
        raise BadInputError(f"{list(roi)} does not lie inside the {width}x{height} image", field="ground_roi")
    hom64 = _check_homography(hom)
    footprint = roi_footprint(hom64, roi)
    if not np.all(np.isfinite(footprint)):
        raise BadInputError("reaches above the horizon of ground_homography", field="ground_roi")
    lo, hi = footprint.min(axis=0), footprint.max(axis=0)
    pad = margin * float(np.max(hi - lo))
    lo, hi = lo - pad, hi + pad
    extent = float(np.max(hi - lo))
    res = math.ceil(extent / max_px * 1000.0) / 1000.0
    if not res > 0:
        raise BadInputError("maps the ground ROI onto a single floor point", field="ground_homography")
    size = (
        max(1, math.ceil((hi[1] - lo[1]) / res)),
        max(1, math.ceil((hi[0] - lo[0]) / res)),
    )  # (cols, rows)
    top, left = hi - 0.5 * res  # floor (x, y) at the centre of the top-left pixel
    floor_from_px = np.array([[0.0, -res, top], [-res, 0.0, left], [0.0, 0.0, 1.0]])
    px_from_view = np.linalg.inv(hom64) @ floor_from_px
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    view = cv2.warpPerspective(
        image, px_from_view, size, flags=flags, borderMode=cv2.BORDER_CONSTANT, borderValue=0
    )
    cols, rows = np.meshgrid(np.arange(size[0], dtype=np.float64), np.arange(size[1], dtype=np.float64))
    w_view = px_from_view[2, 0] * cols + px_from_view[2, 1] * rows + px_from_view[2, 2]
    seen = w_view > 0  # floor in front of the camera (behind it, the warp would show a mirrored image)
    shown = np.asarray(np.where(seen, view, 0), dtype=np.uint8)
    footprint_px = apply_homography(np.linalg.inv(floor_from_px), footprint)
    return BirdsEye(shown, floor_from_px, res, footprint, footprint_px)
