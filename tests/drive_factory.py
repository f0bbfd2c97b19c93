"""Small real drive folders for tests: random-texture PNG frames written with the real writer."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from driftmap.core.odometry.camera import CameraModel
from driftmap.formats.drive_folder import write_drive_folder
from driftmap.formats.records import DriveMeta, FrameRow, GroundingRow

CAMERA = CameraModel(
    width_px=64,
    height_px=48,
    ground_roi_px=(16, 24, 32, 20),
    k_x_m_per_px=0.02,
    k_y_m_per_px=0.03,
    y_c_m=0.0,
    y_h_m=4.0,
)


def frame_png(seed: int, camera: CameraModel = CAMERA) -> bytes:
    """A PNG of random grey texture, distinct per seed."""
    pixels = np.random.default_rng(seed).integers(0, 256, (camera.height_px, camera.width_px), dtype=np.uint8)
    ok, data = cv2.imencode(".png", pixels)
    assert ok
    return bytes(data.tobytes())


def write_test_drive(
    out: Path,
    *,
    name: str = "east-mapping-1",
    frames: int = 12,
    seed: int = 0,
    groundings: bool = True,
    truth: bool = True,
    camera: CameraModel = CAMERA,
) -> Path:
    """Write a drive folder of ``frames`` random frames at 10 fps; returns its path."""
    rows = [
        FrameRow(
            frame=i,
            t_s=round(0.1 * i, 6),
            x_m=12000.0 + 0.37 * i if truth else None,
            y_m=-4.02 + 0.01 * i if truth else None,
            yaw_rad=1.5708 if truth else None,
        )
        for i in range(frames)
    ]
    marks = [
        GroundingRow(frame=0, x_m=12000.1, y_m=-4.0),
        GroundingRow(frame=frames - 1, x_m=12004.2, y_m=-3.9),
    ]
    meta = DriveMeta(name=name, kind="mapping", fps=10.0, camera=camera)
    images = (frame_png(seed * 10_000 + i, camera) for i in range(frames))
    write_drive_folder(out, meta, rows, images, marks if groundings else None)
    return out
