"""The simulated camera: a pinhole or a fisheye on the vehicle, pitched down, and its honest calibration block.

Frames used here:

* camera ``c``: x right, y down, z along the optical axis (OpenCV).
* vehicle foot ``f``: x forward, y left, z up, origin on the floor under the camera centre; the camera
  centre is at (0, 0, height_m).
* look ``l``: the foot frame turned to the way the camera looks (the foot frame itself for a front camera,
  turned half a turn for a rear one). This is the frame of the ``ground_homography`` in ``drive.json``
  (``forward_sign`` -1 says the camera looks backwards).
* world ``w``: mine grid, x east, y north, z up. A pose ``(x, y, yaw)`` puts the foot frame's origin at
  (x, y, 0) and its x axis at angle ``yaw``.

Pixel coordinates ``(u, v)`` are the centre of column u, row v; (0, 0) is the top-left pixel. The
principal point is the image centre ((W - 1) / 2, (H - 1) / 2). A fisheye rig records through the OpenCV
equidistant model (:class:`~driftmap.core.imaging.lens.Lens`); its homography, ROI, ``k_x``, ``k_y`` and
``y_h`` are those of the *undistorted* image, the ideal pinhole of the same ``K``, as ``drive.json``
defines them for a camera with a lens. The camera sits ``y_c_m`` from the rear axle along the way it looks
(paper eq. 1), so a pure rotation of the vehicle about the rear axle moves the floor at the ROI centre
sideways by (y_c + y_h) tan(theta).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.lens import Lens
from driftmap.core.odometry.camera import CameraModel
from driftmap.sim.geometry import FloatArray
from driftmap.sim.params import RIG_DEFAULT, CameraRigParams

__all__ = ["CameraRig"]


@dataclass(frozen=True)
class CameraRig:
    """The vehicle camera: intrinsics, mounting, per-pixel rays and the drive.json camera block."""

    params: CameraRigParams = RIG_DEFAULT

    def __post_init__(self) -> None:
        p = self.params
        if p.facing not in ("front", "rear"):
            raise ValueError(f"CameraRigParams.facing must be front or rear, got {p.facing!r}")
        if p.lens not in ("pinhole", "fisheye") or (p.lens == "pinhole" and p.distortion):
            raise ValueError(f"CameraRigParams.lens must be an ideal pinhole or a fisheye, got {p.lens!r}")

    @property
    def lever_m(self) -> float:
        """Camera foot ahead of the rear axle along the vehicle's forward axis, metres (< 0 behind it)."""
        return self.params.y_c_m if self.params.facing == "front" else -self.params.y_c_m

    @cached_property
    def lens(self) -> Lens | None:
        """The recorded lens: None for the ideal pinhole, else the fisheye's ``K`` and ``k1..k4``."""
        if self.params.lens == "pinhole":
            return None
        k = tuple((float(r[0]), float(r[1]), float(r[2])) for r in self.K)
        return Lens("fisheye", k, tuple(float(c) for c in (*self.params.distortion, 0.0, 0.0, 0.0, 0.0)[:4]))

    @property
    def size_px(self) -> tuple[int, int]:
        """(width, height) of a frame."""
        return self.params.width_px, self.params.height_px

    @cached_property
    def K(self) -> FloatArray:  # noqa: N802
        """Intrinsic matrix, (3, 3)."""
        p = self.params
        return np.array(
            [
                [p.focal_px, 0.0, (p.width_px - 1) / 2],
                [0.0, p.focal_px, (p.height_px - 1) / 2],
                [0.0, 0.0, 1.0],
            ]
        )

    @cached_property
    def lRc(self) -> FloatArray:  # noqa: N802
        """Rotation look-from-camera, (3, 3): columns are the camera axes in the look frame."""
        s, c = math.sin(self.params.pitch_rad), math.cos(self.params.pitch_rad)
        x_c = [0.0, -1.0, 0.0]
        y_c = [-s, 0.0, -c]
        z_c = [c, 0.0, -s]
        return np.array([x_c, y_c, z_c]).T

    @cached_property
    def fRc(self) -> FloatArray:  # noqa: N802
        """Rotation foot-from-camera, (3, 3): the look frame turned half a turn for a rear camera."""
        turn = np.diag([1.0, 1.0, 1.0]) if self.params.facing == "front" else np.diag([-1.0, -1.0, 1.0])
        return np.asarray(turn @ self.lRc)

    @cached_property
    def _normalised(self) -> tuple[FloatArray, FloatArray]:
        """Every pixel's ``((u - cx) / fx, (v - cy) / fy)``, two (H, W) float64 arrays."""
        w, h = self.size_px
        u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        k = self.K
        return (u - k[0, 2]) / k[0, 0], (v - k[1, 2]) / k[1, 1]

    def rays_at(self, u: FloatArray, v: FloatArray) -> FloatArray:
        """Unit rays in the camera frame of recorded pixels ``(u, v)`` (any shape), (..., 3) float64.

        A fisheye pixel at radius ``r`` from the principal point has ``theta_d = r / f``; ``theta`` solves
        ``theta (1 + k1 theta^2 + ... + k4 theta^8) = theta_d`` (Newton). Pixels past ``max_angle_rad`` keep
        the ray at that angle (:attr:`image_circle` marks them).
        """
        k = self.K
        a, b = (np.asarray(u, dtype=np.float64) - k[0, 2]) / k[0, 0], (np.asarray(v) - k[1, 2]) / k[1, 1]
        if self.lens is None:
            d = np.stack([a, b, np.ones_like(a)], axis=-1)
            return np.asarray(d / np.linalg.norm(d, axis=-1, keepdims=True))
        theta_d = np.hypot(a, b)
        theta = _undistort_angle(theta_d, self.lens.distortion, self.params.max_angle_rad)
        scale = np.where(theta_d > 1e-12, np.sin(theta) / np.maximum(theta_d, 1e-12), 1.0)
        return np.stack([a * scale, b * scale, np.cos(theta)], axis=-1)

    @cached_property
    def rays_c(self) -> FloatArray:
        """Unit ray of every recorded pixel in the camera frame, (H, W, 3) float64 (:meth:`rays_at`)."""
        w, h = self.size_px
        u, v = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        return self.rays_at(u, v)

    @cached_property
    def image_circle(self) -> NDArray[np.bool_]:
        """(H, W) True where a pixel sees the scene: everywhere for a pinhole, inside the fisheye's circle."""
        a, b = self._normalised
        if self.lens is None:
            return np.ones(a.shape, dtype=bool)
        limit = float(_distort_angle(np.array(self.params.max_angle_rad), self.lens.distortion))
        return np.asarray(np.hypot(a, b) <= limit)

    @cached_property
    def rays_f(self) -> FloatArray:
        """Unit ray of every recorded pixel in the foot frame, (H, W, 3) float64."""
        return np.asarray(self.rays_c @ self.fRc.T)

    @cached_property
    def homography(self) -> FloatArray:
        """Undistorted pixel (u, v, 1) -> floor point (x, y, w) in the look frame, (3, 3); w > 0 on the floor.

        A floor point P = C + t d with C = (0, 0, h) and d = lRc K^-1 (u, v, 1) has (x, y) = h (d_x, d_y)
        / (-d_z), hence H = diag(h, h, -1) lRc K^-1. Pixels above the horizon give w <= 0.
        """
        h = self.params.height_m
        return np.asarray(np.diag([h, h, -1.0]) @ self.lRc @ np.linalg.inv(self.K))

    def pixel_to_floor(self, u: FloatArray, v: FloatArray) -> FloatArray:
        """Floor points (x, y) in the look frame of undistorted pixels, (..., 2) metres; NaN above horizon."""
        q = np.stack([u, v, np.ones_like(u)], axis=-1) @ self.homography.T
        w = np.where(q[..., 2] > 1e-12, q[..., 2], np.nan)
        return np.asarray(q[..., :2] / w[..., None])

    def floor_to_pixel(self, xy_f: FloatArray) -> FloatArray:
        """Undistorted pixels (u, v) of floor points (x, y) in the look frame, (..., 2)."""
        xy_f = np.asarray(xy_f, dtype=np.float64)
        q = np.concatenate([xy_f, np.ones((*xy_f.shape[:-1], 1))], axis=-1) @ np.linalg.inv(self.homography).T
        return np.asarray(q[..., :2] / q[..., 2:3])

    @cached_property
    def ground_roi_px(self) -> tuple[int, int, int, int]:
        """(x, y, w, h): the widest bottom-centre rectangle seeing only floor in the narrowest tunnel.

        Every pixel of the ROI must hit the floor inside a tunnel of ``tunnel_width_m`` for a camera
        up to ``max_offset_m`` off the centreline and a heading up to ``max_yaw_dev_rad`` off its axis.
        """
        p = self.params
        w, h = self.size_px
        v1 = h - 1 - p.roi_bottom_margin_px
        v0 = v1 - p.roi_height_px + 1
        cx = (w - 1) / 2
        best = 1
        for half in range(1, w // 2):
            u0, u1 = math.floor(cx - half + 0.5), math.ceil(cx + half - 0.5)
            uu, vv = np.meshgrid(
                np.arange(u0, u1 + 1, dtype=np.float64), np.arange(v0, v1 + 1, dtype=np.float64)
            )
            xy = self.pixel_to_floor(uu, vv)
            if not np.all(np.isfinite(xy)):
                break
            dev = p.max_yaw_dev_rad
            lateral = np.abs(xy[..., 1]) * math.cos(dev) + xy[..., 0] * math.sin(dev) + p.max_offset_m
            if np.max(lateral) > p.tunnel_width_m / 2:
                break
            best = half
        u0 = math.floor(cx - best + 0.5)
        return (u0, v0, 2 * best, p.roi_height_px)

    @cached_property
    def camera_model(self) -> CameraModel:
        """The drive.json camera block computed from this geometry (k_x, k_y, y_h at the ROI centre)."""
        x, y, w, h = self.ground_roi_px
        uc, vc = x + (w - 1) / 2, y + (h - 1) / 2
        up, down = self.pixel_to_floor(np.array([uc, uc]), np.array([vc - 0.5, vc + 0.5]))
        left, right = self.pixel_to_floor(np.array([uc - 0.5, uc + 0.5]), np.array([vc, vc]))
        centre = self.pixel_to_floor(np.array(uc), np.array(vc))
        H = self.homography
        return CameraModel(
            width_px=self.params.width_px,
            height_px=self.params.height_px,
            ground_roi_px=self.ground_roi_px,
            k_x_m_per_px=float(abs(right[1] - left[1])),
            k_y_m_per_px=float(abs(up[0] - down[0])),
            y_c_m=float(self.params.y_c_m),
            y_h_m=float(centre[0]),
            forward_sign=1 if self.params.facing == "front" else -1,
            ground_homography=tuple((float(r[0]), float(r[1]), float(r[2])) for r in H),
            lens=self.lens,
        )


def _distort_angle(theta: FloatArray, k: tuple[float, ...]) -> FloatArray:
    """OpenCV fisheye ``theta_d = theta (1 + k1 theta^2 + k2 theta^4 + k3 theta^6 + k4 theta^8)``."""
    t2 = theta * theta
    return np.asarray(theta * (1 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3])))))


def _undistort_angle(theta_d: FloatArray, k: tuple[float, ...], max_angle_rad: float) -> FloatArray:
    """The ``theta`` in [0, max_angle_rad] whose :func:`_distort_angle` is ``theta_d`` (Newton, 8 steps)."""
    theta = np.clip(theta_d, 0.0, max_angle_rad)
    for _ in range(8):
        t2 = theta * theta
        f = _distort_angle(theta, k) - theta_d
        df = 1 + t2 * (3 * k[0] + t2 * (5 * k[1] + t2 * (7 * k[2] + t2 * 9 * k[3])))
        theta = np.clip(theta - f / df, 0.0, max_angle_rad)
    return np.asarray(theta)
