"""The thumbnail view of a camera: frames undistorted to one pinhole view before place recognition.

Loop closure, the SESAME database and the localiser compare small patch-normalised thumbnails
(:func:`driftmap.core.imaging.images.preprocess`). A camera with a lens (:mod:`driftmap.core.imaging.lens`)
records a distorted image, in which the same place seen a little off-centre changes shape; its frames are
therefore first resampled to the camera's **thumbnail view**, an ideal pinhole image of the frame's size
(``docs/design/cameras.md``):

- principal point and aspect ratio (``fy / fx``, skew) of the lens's ``K``;
- focal length ``fx_v = max(fx, (W / 2) / tan(50 deg))``: the undistorted image of ``K`` itself (what
  odometry samples) unless that is wider than :data:`VIEW_MAX_HFOV_DEG` = 100 degrees across the width,
  in which case the view is narrowed to 100 degrees. A strong fisheye's ``K`` as a pinhole spans 110-120
  degrees (a 180-degree equidistant fisheye across the width: 2 atan(pi / 2) = 115 degrees), whose sides a
  pinhole stretches radially by 1 / cos^2 (three times at 55 degrees off the axis) out of few raw pixels;
  at 100 degrees the stretch at the sides is 2.4x and the view still holds the walls, floor and roof of a
  rear camera's tunnel. An ordinary lens (under 100 degrees) keeps exactly its ``K``.

The view depends on the lens and the frame size only, so a map's frames and a live vehicle's query frames of
one camera land in the same view and compare. The remap tables (:class:`ViewMaps`, the whole frame) are
built once per lens and frame size (:func:`view_maps`, cached); each frame then costs one ``cv2.remap``. A
camera without a lens, or whose lens is an undistorted pinhole under 100 degrees, is its own view: frames
pass untouched and thumbnails are bit-identical to ``preprocess`` of the recorded frame. Pixels are
``(u, v)``: u right, v down, origin at the top-left pixel's centre.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import Any, TypeVar

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.images import preprocess, to_gray
from driftmap.core.imaging.lens import Lens, project_rays
from driftmap.core.imaging.params import ImageParams
from driftmap.errors import BadInputError

__all__ = ["VIEW_MAX_HFOV_DEG", "ViewMaps", "thumbnails", "undistorted_view", "view_maps", "view_matrix"]

_G = TypeVar("_G", bound="np.integer[Any] | np.floating[Any]")  # dtypes cv2.remap takes

VIEW_MAX_HFOV_DEG = 100.0
"""Widest horizontal field of view of a thumbnail view, degrees (across the frame's width)."""


def view_matrix(lens: Lens, size: tuple[int, int]) -> NDArray[np.float64]:
    """The camera matrix of a lens's thumbnail view (module docstring).

    Args:
        lens: the camera's lens.
        size: ``(width, height)`` of the frames, pixels.

    Returns:
        ``(3, 3)`` float64 ``K_v``: ``K`` with its first two rows' focal terms scaled by
        ``max(1, f_min / fx)``, ``f_min = (width / 2) / tan(VIEW_MAX_HFOV_DEG / 2)`` pixels.
    """
    width = int(size[0])
    if width <= 0 or int(size[1]) <= 0:
        raise BadInputError(f"frame size must be positive, got {size}", field="size")
    k = lens.matrix()
    f_min = (width / 2.0) / math.tan(math.radians(VIEW_MAX_HFOV_DEG / 2.0))
    scale = max(1.0, f_min / float(k[0, 0]))
    k[0, 0] *= scale
    k[0, 1] *= scale
    k[1, 1] *= scale
    return k


class ViewMaps:
    """Remap tables from a raw frame to its camera's thumbnail view (whole frame), built once per lens and size.

    Attributes:
        size: ``(width, height)`` of the frames, pixels.
        matrix: ``(3, 3)`` camera matrix of the view (:func:`view_matrix`), pixels.
        identity: the lens needs no resampling (a pinhole without distortion whose view is its ``K``):
            :meth:`apply` returns the frame itself and no tables are built.
    """

    def __init__(self, lens: Lens, size: tuple[int, int]) -> None:
        """Build the tables: for every view pixel, the raw pixel its ray lands on.

        Args:
            lens: the camera's lens.
            size: ``(width, height)`` of the frames, pixels.
        """
        width, height = int(size[0]), int(size[1])
        self.size = (width, height)
        self.matrix = view_matrix(lens, self.size)
        self.identity = (
            lens.model == "pinhole"
            and not any(lens.distortion)
            and np.array_equal(self.matrix, lens.matrix())
        )
        if self.identity:
            return
        uu, vv = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
        pix = np.stack([uu.ravel(), vv.ravel(), np.ones(uu.size)])
        rays = np.linalg.solve(self.matrix, pix).T  # (H * W, 3), z = 1
        raw = project_rays(lens, rays).reshape(height, width, 2)
        raw = np.where(np.isfinite(raw), raw, -1e6).astype(np.float32)
        self._map1, self._map2 = cv2.convertMaps(raw[..., 0], raw[..., 1], cv2.CV_16SC2)

    def apply(self, gray: NDArray[_G]) -> NDArray[_G]:
        """The view of one frame: ``(H, W)`` grey in (uint8, uint16 or float32), ``(H, W)`` same dtype out.

        Bilinear; a view pixel whose ray lands outside the raw frame takes the nearest edge pixel. The frame
        itself when :attr:`identity`.
        """
        width, height = self.size
        if gray.shape != (height, width):
            raise BadInputError(f"must be a ({height}, {width}) grey frame, got {gray.shape}", field="frame")
        if self.identity:
            return gray
        out = cv2.remap(gray, self._map1, self._map2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        return np.asarray(out, dtype=gray.dtype)


@lru_cache(maxsize=8)
def view_maps(lens: Lens, size: tuple[int, int]) -> ViewMaps:
    """The (cached) :class:`ViewMaps` of a lens and ``(width, height)``: one build per camera and frame size.

    ``view_maps.cache_info().misses`` counts the builds.
    """
    return ViewMaps(lens, size)


def undistorted_view(frame: NDArray[_G], lens: Lens | None) -> NDArray[_G]:
    """A frame as its camera's thumbnail view sees it.

    Args:
        frame: one grey ``(H, W)`` frame, or colour ``(H, W, 3|4)`` (BGR), any dtype OpenCV remaps.
        lens: the camera's lens; None: the frame is returned as given (the same object).

    Returns:
        ``(H, W)`` grey frame of the input's dtype (the input itself when ``lens`` is None).
    """
    if lens is None:
        return frame
    gray = np.asarray(to_gray(np.asarray(frame)))
    if gray.ndim != 2:
        raise BadInputError(f"must be one (H, W) or (H, W, C) frame, got {np.shape(frame)}", field="frame")
    return view_maps(lens, (int(gray.shape[1]), int(gray.shape[0]))).apply(gray)


def thumbnails(images: NDArray[np.generic], params: ImageParams, lens: Lens | None) -> NDArray[np.float32]:
    """Place-recognition thumbnails of a camera's frames: its thumbnail view, then the IV-C chain.

    Args:
        images: one frame ``(H, W)`` / ``(H, W, 3)`` or a stack ``(N, H, W)`` / ``(N, H, W, 3)`` as recorded.
        params: crop, thumbnail size and patch size (:func:`driftmap.core.imaging.images.preprocess`).
        lens: the camera's lens; None: exactly ``preprocess(images, params)``.

    Returns:
        float32 ``(h, w)`` or ``(N, h, w)`` patch-normalised thumbnails, ``(w, h) = params.size_px``.
    """
    if lens is None:
        return preprocess(images, params)
    gray = np.asarray(to_gray(np.asarray(images)))
    if gray.ndim == 2:
        return preprocess(undistorted_view(gray, lens), params)
    return preprocess(np.stack([undistorted_view(g, lens) for g in gray]), params)
