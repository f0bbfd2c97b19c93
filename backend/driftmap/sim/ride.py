"""How a real vehicle camera departs from its calibration: ride bounce, motion blur, calibration error.

The renderer draws every frame from the nominal camera mounting; a real camera on a load-haul-dump vehicle
does not hold still. This module adds the three effects that make real ground-plane odometry drift:

* **Ride bounce.** Suspension and an uneven floor pitch and roll the camera by a degree or so at 1-3 Hz,
  more at speed. A camera rotation about its centre moves every pixel along its ray whatever the depth, so
  :func:`apply_ride` warps the rendered frame exactly (a pinhole by the homography K R K^-1, a fisheye
  through its lens). Odometry, which assumes the
  calibrated mounting, sees a slightly wrong floor scale and lateral shift in every frame.
* **Motion blur.** The floor streaks along the image column during the exposure; :func:`apply_ride`
  blurs vertically by the floor motion of the exposure time, in pixels at the ground ROI centre.
* **Mount yaw.** The camera looks a fraction of a degree left or right of the vehicle axis, which no
  drive.json field describes; odometry sees the floor slide diagonally, as with a real bracket.
* **Calibration error.** drive.json carries a calibration measured once per vehicle, not the truth:
  :func:`calibrated_rig` perturbs the camera height (scale) and pitch per drive, so two drives disagree in
  scale by about a percent, as two vehicles of a real fleet do.

Angles are radians, lengths metres, times seconds; images (H, W) uint8.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import cv2
import numpy as np

from driftmap.core.imaging.lens import project_rays
from driftmap.sim.geometry import FloatArray
from driftmap.sim.rig import CameraRig

__all__ = ["RIDE_DEFAULT", "RIDE_NONE", "RideParams", "apply_ride", "calibrated_rig", "ride_motion"]


@dataclass(frozen=True)
class RideParams:
    """Amplitudes of ride bounce, blur and calibration error (see the module docstring)."""

    pitch_bounce_rad: float = math.radians(
        0.8
    )  # standard deviation of camera pitch bounce at reference speed
    roll_bounce_rad: float = math.radians(0.6)  # standard deviation of camera roll bounce at reference speed
    bounce_hz: tuple[float, float] = (0.7, 2.5)  # band of bounce frequencies
    reference_speed_mps: float = 5.0  # bounce grows as sqrt(speed / this); 0.25 of it when standing
    exposure_s: float = 0.008  # exposure time giving the motion blur
    height_error_frac: float = 0.012  # standard deviation of the calibrated camera height error (scale)
    pitch_error_rad: float = math.radians(0.4)  # standard deviation of the calibrated pitch error
    yaw_mount_rad: float = math.radians(
        0.7
    )  # standard deviation of the camera's uncalibrated yaw on its mount


RIDE_DEFAULT = RideParams()
RIDE_NONE = RideParams(
    0.0, 0.0, exposure_s=0.0, height_error_frac=0.0, pitch_error_rad=0.0, yaw_mount_rad=0.0
)


def ride_motion(
    t_s: FloatArray, speed_mps: FloatArray, rng: np.random.Generator, params: RideParams
) -> FloatArray:
    """Camera pitch and roll bounce of one drive, (n, 2) radians (pitch down positive, roll).

    Each angle is a sum of eight sinusoids with random frequencies in ``bounce_hz`` and random phases,
    scaled to the configured standard deviation and by sqrt(speed / reference_speed_mps) (at least 0.25),
    so the camera is steady at a stop and shakes over a rough floor at speed. The mount yaw is one draw
    per drive, constant over it.

    Args:
        t_s: (n,) frame times, seconds.
        speed_mps: (n,) vehicle speed at each frame, metres per second.
        rng: the drive's random generator.
        params: amplitudes.
    """
    t = np.asarray(t_s, dtype=np.float64)
    gain = np.sqrt(np.maximum(np.abs(speed_mps) / params.reference_speed_mps, 0.0625))
    out = np.zeros((len(t), 3))
    for k, sigma in enumerate((params.pitch_bounce_rad, params.roll_bounce_rad)):
        if sigma <= 0:
            continue
        f = rng.uniform(*params.bounce_hz, size=8)
        phase = rng.uniform(0.0, 2 * np.pi, size=8)
        wave = np.sin(2 * np.pi * t[:, None] * f[None, :] + phase[None, :]).sum(axis=1)
        out[:, k] = sigma * gain * wave / math.sqrt(8 / 2)  # eight unit sinusoids have variance 4
    out[:, 2] = params.yaw_mount_rad * float(rng.standard_normal())
    return out


def _rotation(rig: CameraRig, pitch_rad: float, roll_rad: float, yaw_rad: float) -> FloatArray:
    """(3, 3) rotation taking a ray of the nominal camera to the camera pitched down, rolled and yawed.

    Pitch turns about the camera x axis, roll about the optical axis, yaw about the vehicle's vertical
    (the foot frame's z axis expressed in camera coordinates).
    """
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    pitch = np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]])
    roll = np.array([[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])
    up_c = rig.fRc.T @ np.array([0.0, 0.0, 1.0])
    yaw, _ = cv2.Rodrigues(np.asarray(up_c * -yaw_rad, dtype=np.float64))
    return np.asarray(roll @ pitch @ np.asarray(yaw))


def _turn_fisheye(img: np.ndarray, rig: CameraRig, c_R_nominal: FloatArray) -> np.ndarray:
    """The fisheye frame of the turned camera: each pixel samples the nominal frame where its ray fell.

    A recorded pixel with ray ``r`` (camera frame) saw the nominal camera's ray ``R^T r``, projected through
    the lens (:func:`~driftmap.core.imaging.lens.project_rays`) and sampled bilinearly. A ray turned behind
    the lens plane (the rim of a 180-degree view) and pixels outside the image circle are black.
    """
    lens = rig.lens
    assert lens is not None
    h, w = img.shape[:2]
    src = (rig.rays_c @ c_R_nominal).reshape(-1, 3)
    ahead = src[:, 2] > 1e-6
    raw = np.full((len(src), 2), -1.0)
    raw[ahead] = project_rays(lens, src[ahead])
    maps = raw.reshape(h, w, 2).astype(np.float32)
    out = cv2.remap(
        img, maps[..., 0], maps[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0
    )
    return np.asarray(np.where(rig.image_circle, out, 0).astype(img.dtype))


def apply_ride(
    img: np.ndarray, rig: CameraRig, pitch_rad: float, roll_rad: float, yaw_rad: float, blur_px: float
) -> np.ndarray:
    """The frame seen by the bounced camera: rotation warp, then vertical motion blur.

    A pinhole frame is warped by the homography ``K R K^-1``; a fisheye frame is resampled through its lens
    (:func:`_turn_fisheye`).

    Args:
        img: (H, W) uint8 frame rendered from the nominal mounting.
        rig: the nominal camera.
        pitch_rad, roll_rad, yaw_rad: the camera's rotation from its nominal mounting at this frame.
        blur_px: length of the vertical motion streak, pixels (below 1: no blur).
    """
    out = img
    if pitch_rad != 0.0 or roll_rad != 0.0 or yaw_rad != 0.0:
        c_R_nominal = _rotation(rig, pitch_rad, roll_rad, yaw_rad)
        if rig.lens is not None:
            out = _turn_fisheye(out, rig, c_R_nominal)
        else:
            K = rig.K
            H = K @ c_R_nominal @ np.linalg.inv(K)
            out = cv2.warpPerspective(
                out, H, (img.shape[1], img.shape[0]), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT101
            )
    if blur_px >= 1.0:
        n = math.ceil(blur_px)
        kernel = np.full((n, 1), 1.0 / blur_px, np.float32)
        kernel[-1, 0] = 1.0 - (n - 1) / blur_px  # fractional last tap: the streak is exactly blur_px long
        out = cv2.filter2D(out, -1, kernel, borderType=cv2.BORDER_REPLICATE)
    return np.asarray(out)


def floor_px_per_m(rig: CameraRig) -> float:
    """Image motion at the ground ROI centre per metre of forward travel, pixels."""
    x, y, w, h = rig.ground_roi_px
    uc, vc = x + (w - 1) / 2, y + (h - 1) / 2
    near, far = rig.pixel_to_floor(np.array([uc, uc]), np.array([vc + 0.5, vc - 0.5]))
    return float(1.0 / max(far[0] - near[0], 1e-9))


def calibrated_rig(rig: CameraRig, rng: np.random.Generator, params: RideParams) -> CameraRig:
    """The rig as a per-drive calibration measured it: height and pitch off by the configured errors."""
    p = rig.params
    height = p.height_m * (1.0 + params.height_error_frac * float(rng.standard_normal()))
    pitch = p.pitch_rad + params.pitch_error_rad * float(rng.standard_normal())
    return CameraRig(replace(p, height_m=height, pitch_rad=pitch))
