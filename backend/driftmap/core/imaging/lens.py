"""Lens models of a real camera and the undistortion of the image region a pipeline step needs.

Two models, as OpenCV defines them (``docs/design/cameras.md``):

- ``pinhole``: a pinhole with radial-tangential distortion, coefficients ``k1 k2 p1 p2 [k3]``
  (OpenCV ``calib3d``);
- ``fisheye``: the equidistant fisheye, ``r = f * theta_d`` with ``theta_d = theta (1 + k1 theta^2 +
  k2 theta^4 + k3 theta^6 + k4 theta^8)``, coefficients ``k1 k2 k3 k4`` (OpenCV ``fisheye``).

The *undistorted image* of a lens is the ideal pinhole image of the same size and the same camera
matrix ``K``: a raw pixel ``p`` and its undistorted pixel ``q`` see the same ray. The ground ROI, ``k_x``,
``k_y``, ``y_h`` and the ground homography of a camera with a lens are defined on that image. Pixel
coordinates are ``(u, v)``: u right, v down, origin at the top-left pixel's centre, in pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.errors import BadInputError

__all__ = [
    "LENS_MODELS",
    "Lens",
    "LensMaps",
    "LensModel",
    "distort_points",
    "lens_maps",
    "project_rays",
    "undistort_image",
    "undistort_points",
]

LensModel = Literal["pinhole", "fisheye"]
LENS_MODELS: tuple[str, ...] = ("pinhole", "fisheye")
_N_COEFFS: dict[str, tuple[int, ...]] = {"pinhole": (4, 5), "fisheye": (4,)}
Rect = tuple[int, int, int, int]


@dataclass(frozen=True)
class Lens:
    """The intrinsics of one camera.

    Attributes:
        model: ``"pinhole"`` (radial-tangential) or ``"fisheye"`` (equidistant).
        K: camera matrix ``((fx, 0, cx), (0, fy, cy), (0, 0, 1))``, pixels (skew allowed in ``K[0][1]``).
        distortion: ``(k1, k2, p1, p2[, k3])`` for pinhole, ``(k1, k2, k3, k4)`` for fisheye.
    """

    model: LensModel
    K: tuple[tuple[float, float, float], ...]
    distortion: tuple[float, ...]

    def __post_init__(self) -> None:
        if self.model not in LENS_MODELS:
            raise BadInputError(
                f"must be one of {', '.join(LENS_MODELS)}, found {self.model!r}", field="lens.model"
            )
        k = np.asarray(self.K, dtype=np.float64)
        if k.shape != (3, 3) or not np.all(np.isfinite(k)):
            raise BadInputError("must be a 3x3 matrix of finite numbers", field="lens.K")
        if k[0, 0] <= 0 or k[1, 1] <= 0 or k[1, 0] != 0 or tuple(k[2]) != (0.0, 0.0, 1.0):
            raise BadInputError(
                "must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0", field="lens.K"
            )
        counts = _N_COEFFS[self.model]
        if len(self.distortion) not in counts or not all(math.isfinite(c) for c in self.distortion):
            names = "k1 k2 p1 p2 [k3]" if self.model == "pinhole" else "k1 k2 k3 k4"
            raise BadInputError(
                f"a {self.model} lens needs {' or '.join(map(str, counts))} finite coefficients ({names}),"
                f" found {len(self.distortion)}",
                field="lens.distortion",
            )

    def matrix(self) -> NDArray[np.float64]:
        """``K`` as a (3, 3) float64 array, pixels."""
        return np.asarray(self.K, dtype=np.float64)

    def coeffs(self) -> NDArray[np.float64]:
        """The distortion coefficients as a (D,) float64 array (D = 4 or 5)."""
        return np.asarray(self.distortion, dtype=np.float64)


def _check_points(points: NDArray, name: str) -> NDArray[np.float64]:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise BadInputError(f"must be an (N, 2) array of pixels, got shape {pts.shape}", field=name)
    return pts


def undistort_points(lens: Lens, points_px: NDArray) -> NDArray[np.float64]:
    """Raw pixels to undistorted pixels (same ``K``).

    Args:
        lens: the camera's lens.
        points_px: ``(N, 2)`` raw image pixels ``(u, v)``.

    Returns:
        ``(N, 2)`` float64 pixels of the same rays in the undistorted image. Fisheye rays at or beyond 90
        degrees off the axis have no pinhole image; their coordinates are not finite or meaningless.
    """
    pts = _check_points(points_px, "points_px").reshape(-1, 1, 2)
    if len(pts) == 0:
        return np.zeros((0, 2))
    k = lens.matrix()
    if lens.model == "fisheye":
        out = cv2.fisheye.undistortPoints(pts, k, lens.coeffs(), P=k)
    else:
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-9)
        out = cv2.undistortPoints(pts, k, lens.coeffs(), R=None, P=k, criteria=crit)
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


def distort_points(lens: Lens, points_px: NDArray) -> NDArray[np.float64]:
    """Undistorted pixels to raw pixels: where in the recorded frame each ideal pixel's ray lands.

    Args:
        lens: the camera's lens.
        points_px: ``(N, 2)`` pixels ``(u, v)`` of the undistorted image.

    Returns:
        ``(N, 2)`` float64 raw image pixels.
    """
    pts = _check_points(points_px, "points_px")
    return project_rays(lens, np.linalg.solve(lens.matrix(), np.vstack([pts.T, np.ones(len(pts))])).T)


def project_rays(lens: Lens, rays: NDArray) -> NDArray[np.float64]:
    """Camera-frame rays to raw pixels: where in the recorded frame each ray lands.

    Args:
        lens: the camera's lens.
        rays: ``(N, 3)`` rays ``(x, y, z)`` in the camera frame (x right, y down, z along the axis), z > 0;
            any length (typically z = 1).

    Returns:
        ``(N, 2)`` float64 raw image pixels ``(u, v)``.
    """
    r = np.asarray(rays, dtype=np.float64)
    if r.ndim != 2 or r.shape[1] != 3:
        raise BadInputError(f"must be an (N, 3) array of rays, got shape {r.shape}", field="rays")
    if len(r) == 0:
        return np.zeros((0, 2))
    k, zero = lens.matrix(), np.zeros(3)
    if lens.model == "fisheye":
        out, _ = cv2.fisheye.projectPoints(r.reshape(-1, 1, 3), zero, zero, k, lens.coeffs())
    else:
        out, _ = cv2.projectPoints(r.reshape(-1, 1, 3), zero, zero, k, lens.coeffs())
    return np.asarray(out, dtype=np.float64).reshape(-1, 2)


class LensMaps:
    """Remap tables from a raw frame to a window of its undistorted image, built once per camera.

    ``apply`` remaps only the window and pads the rest of the frame by replicating the window's edge, so
    the result has the raw frame's shape and is exact inside ``window``.
    """

    def __init__(self, lens: Lens, size: tuple[int, int], window: Rect) -> None:
        """Build the tables.

        Args:
            lens: the camera's lens.
            size: ``(width, height)`` of the frames, pixels.
            window: ``(x, y, w, h)`` rectangle of the undistorted image to compute, inside the frame.
        """
        width, height = size
        x, y, w, h = window
        if w <= 0 or h <= 0 or x < 0 or y < 0 or x + w > width or y + h > height:
            raise BadInputError(f"{window} does not fit a {width}x{height} frame", field="window")
        self.size = (int(width), int(height))
        self.window = (int(x), int(y), int(w), int(h))
        uu, vv = np.meshgrid(np.arange(x, x + w, dtype=np.float64), np.arange(y, y + h, dtype=np.float64))
        raw = distort_points(lens, np.stack([uu.ravel(), vv.ravel()], axis=1)).reshape(h, w, 2)
        raw = np.where(np.isfinite(raw), raw, -1e6).astype(np.float32)
        self._map1, self._map2 = cv2.convertMaps(raw[..., 0], raw[..., 1], cv2.CV_16SC2)

    def apply(self, frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """The undistorted frame: ``(H, W)`` uint8 in, ``(H, W)`` uint8 out (exact inside the window)."""
        width, height = self.size
        if frame.shape[:2] != (height, width):
            raise BadInputError(f"must be a ({height}, {width}) frame, got {frame.shape}", field="frame")
        inner = cv2.remap(frame, self._map1, self._map2, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        x, y, w, h = self.window
        if (w, h) == (width, height):
            return np.asarray(inner, dtype=np.uint8)
        out = cv2.copyMakeBorder(inner, y, height - y - h, x, width - x - w, cv2.BORDER_REPLICATE)
        return np.asarray(out, dtype=np.uint8)


@lru_cache(maxsize=16)
def lens_maps(lens: Lens, size: tuple[int, int], window: Rect) -> LensMaps:
    """The (cached) :class:`LensMaps` of a lens, frame size and window."""
    return LensMaps(lens, size, window)


def undistort_image(lens: Lens, frame: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """The undistorted image of a whole frame: the ideal pinhole image of the same size and the same ``K``.

    The image the ground ROI and homography of a camera with a lens refer to (module docstring), not the
    thumbnail view of :mod:`driftmap.core.imaging.views`, which narrows wide lenses. Bilinear; a pixel whose
    ray lands outside the recorded frame takes the nearest edge pixel. The remap tables are those of
    :func:`lens_maps` over the whole frame (cached per lens and size).

    Args:
        lens: the camera's lens.
        frame: ``(H, W)`` uint8 grey frame as recorded.

    Returns:
        ``(H, W)`` uint8 undistorted frame.
    """
    if frame.ndim != 2:
        raise BadInputError(f"must be a grey (H, W) frame, got shape {frame.shape}", field="frame")
    height, width = frame.shape
    return lens_maps(lens, (int(width), int(height)), (0, 0, int(width), int(height))).apply(frame)
