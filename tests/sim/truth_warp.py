"""Frames against ground truth: frame k warped through the recorded poses and the ground homography onto frame k+1."""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.formats.drive_folder import DriveFolder


def ncc_predicted(
    folder: DriveFolder, k: int, error_m: float, image: Callable[[int], NDArray[np.float32]]
) -> float:
    """NCC between frame k+1's ROI and frame k warped onto it through the recorded poses (the later pose moved
    ``error_m`` sideways) and the ground homography, after removing local means.

    ``image(i)`` is frame i as the homography sees it (float32; undistorted for a camera with a lens). The
    homography is in the camera's look frame: the vehicle's frame, turned half a turn when ``forward_sign``
    is -1 (a camera looking behind).
    """
    cam = folder.meta.camera
    hom = cam.homography()
    assert hom is not None
    x, y, w, h = cam.ground_roi_px
    uu, vv = np.meshgrid(np.arange(x, x + w, dtype=float), np.arange(y, y + h, dtype=float))
    q = np.stack([uu, vv, np.ones_like(uu)], axis=-1) @ hom.T
    look1 = q[..., :2] / q[..., 2:]
    r0, r1 = folder.frames[k], folder.frames[k + 1]
    assert r0.yaw_rad is not None and r1.yaw_rad is not None
    turn = 0.0 if cam.forward_sign == 1 else math.pi
    c1, s1 = math.cos(r1.yaw_rad + turn), math.sin(r1.yaw_rad + turn)
    p1 = np.array([r1.x_m, r1.y_m], dtype=float) + error_m * np.array([-s1, c1])
    world = p1 + look1 @ np.array([[c1, s1], [-s1, c1]])
    c0, s0 = math.cos(r0.yaw_rad + turn), math.sin(r0.yaw_rad + turn)
    look0 = (world - np.array([r0.x_m, r0.y_m], dtype=float)) @ np.array([[c0, -s0], [s0, c0]])
    p = np.concatenate([look0, np.ones((*look0.shape[:-1], 1))], axis=-1) @ np.linalg.inv(hom).T
    mx, my = (p[..., 0] / p[..., 2]).astype(np.float32), (p[..., 1] / p[..., 2]).astype(np.float32)

    def flat(img: NDArray[np.float32]) -> NDArray[np.float32]:
        return np.asarray(img - cv2.GaussianBlur(img, (0, 0), 4.0), dtype=np.float32)

    predicted = cv2.remap(flat(image(k)), mx, my, cv2.INTER_LINEAR)
    actual = flat(image(k + 1))[y : y + h, x : x + w]
    a, b = predicted - predicted.mean(), actual - actual.mean()
    return float((a * b).sum() / math.sqrt((a * a).sum() * (b * b).sum()))
