"""Synthetic floors seen by a calibrated camera, for odometry and localisation tests with known motion."""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.drive import compose, shift_horizon

SEED = 11
TEX_RES_M = 0.005  # floor texture, metres per texel
PATCH_M = ((1.6, 2.2), (0.3, 0.7))  # a bright floor patch: x from..to (along the look), y from..to (left)


def floor_texture(size: int = 2400, seed: int = SEED) -> np.ndarray:
    """Gravel-like multi-scale texture, uint8."""
    rng = np.random.default_rng(seed)
    tex = np.zeros((size, size), np.float32)
    for sigma, weight in ((1.0, 0.6), (3.0, 1.0), (8.0, 1.0), (20.0, 0.8)):
        layer = cv2.GaussianBlur(rng.standard_normal((size, size)).astype(np.float32), (0, 0), sigma)
        tex += weight * layer / layer.std()
    return np.asarray(np.clip(128 + 30 * tex / tex.std(), 0, 255), dtype=np.uint8)


def pinhole_camera(pitch_deg: float = 35.0, height_m: float = 2.0, y_c_m: float = 1.5) -> CameraModel:
    """320x240 camera pitched down over the floor, ROI on the lower image, like the simulated mine."""
    width, height, f = 320, 240, 250.0
    phi = math.radians(pitch_deg)
    k = np.array([[f, 0, width / 2], [0, f, height / 2], [0, 0, 1]])
    rows = [
        [0, -1, 0],
        [-math.sin(phi), 0, height_m * math.cos(phi)],
        [math.cos(phi), 0, height_m * math.sin(phi)],
    ]
    hom = np.linalg.inv(k @ np.array(rows))  # pixel -> floor (x forward, y left)
    hom /= np.abs(hom).max()
    hom *= np.sign(hom[2] @ [width / 2, height - 1, 1])
    roi = (60, 130, 200, 90)
    rows3 = tuple((float(r[0]), float(r[1]), float(r[2])) for r in hom)
    cam = CameraModel(width, height, roi, 0.01, 0.01, y_c_m, 2.0, 1, rows3)
    return shift_horizon(cam, 0.0)  # k_x, k_y, y_h from the homography at the ROI centre


def render(tex: np.ndarray, camera: CameraModel, wT: tuple[float, float, float]) -> np.ndarray:
    """Frame seen by the camera whose floor point has world pose wT (texture centred on the origin)."""
    half = tex.shape[0] * TEX_RES_M / 2
    x, y, yaw = wT
    c, s = math.cos(yaw), math.sin(yaw)
    world_from_vehicle = np.array([[c, -s, x], [s, c, y], [0, 0, 1]])
    texel_from_world = np.array(
        [[1 / TEX_RES_M, 0, half / TEX_RES_M], [0, -1 / TEX_RES_M, half / TEX_RES_M], [0, 0, 1]]
    )
    m = texel_from_world @ world_from_vehicle @ np.asarray(camera.homography())
    flags = cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP
    return np.asarray(cv2.warpPerspective(tex, m, (camera.width_px, camera.height_px), flags=flags))


def patch_frame(hom: NDArray[np.float64], size: tuple[int, int]) -> NDArray[np.uint8]:
    """(H, W) frame of a dark floor (x 0..8 m, y -4..4 m) with the bright ``PATCH_M`` seen through ``hom``."""
    n = round(8.0 / TEX_RES_M)
    floor = np.full((n, n), 60, np.uint8)
    (x0, x1), (y0, y1) = PATCH_M
    floor[
        round((8 - x1) / TEX_RES_M) : round((8 - x0) / TEX_RES_M),
        round((4 - y1) / TEX_RES_M) : round((4 - y0) / TEX_RES_M),
    ] = 230
    texel_from_floor = np.array(
        [[0.0, -1 / TEX_RES_M, 4 / TEX_RES_M], [-1 / TEX_RES_M, 0.0, 8 / TEX_RES_M], [0, 0, 1]]
    )
    flags = cv2.INTER_AREA | cv2.WARP_INVERSE_MAP
    return np.asarray(cv2.warpPerspective(floor, texel_from_floor @ hom, size, flags=flags), dtype=np.uint8)


def arc_step(
    wT: tuple[float, float, float], d: float, theta: float, y_c: float
) -> tuple[float, float, float]:
    """Pose after a rear-axle arc of chord d and turn theta (the model documented in odometry)."""
    tx = d * math.cos(theta / 2) + y_c * (math.cos(theta) - 1)
    ty = d * math.sin(theta / 2) + y_c * math.sin(theta)
    x, y, yaw = compose(wT, (tx, ty, theta))
    return float(x), float(y), float(yaw)
