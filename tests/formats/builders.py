"""Shared builders for the formats tests: a small camera, drive metadata and frames."""

from __future__ import annotations

import cv2
import numpy as np

from driftmap.core.odometry.camera import CameraModel
from driftmap.formats.records import DriveMeta, FrameRow, GroundingRow

WIDTH_PX, HEIGHT_PX = 32, 24


def make_camera(*, homography: bool = False) -> CameraModel:
    """A 32x24 camera with awkward floats, optionally with a ground homography."""
    return CameraModel(
        width_px=WIDTH_PX,
        height_px=HEIGHT_PX,
        ground_roi_px=(4, 12, 24, 10),
        k_x_m_per_px=0.1 + 0.2,
        k_y_m_per_px=1 / 3,
        y_c_m=-0.7,
        y_h_m=4.000000000000001,
        forward_sign=-1,
        ground_homography=((1.0, 0.0, -16.0), (0.0, 1 / 7, 2.5e-9), (0.0, 0.0, 1.0)) if homography else None,
    )


def make_meta(*, homography: bool = False, kind: str = "mapping") -> DriveMeta:
    return DriveMeta(name="east-mapping-1", kind=kind, fps=10.0, camera=make_camera(homography=homography))  # type: ignore[arg-type]


def make_frames(n: int = 5, *, truth: bool = True) -> list[FrameRow]:
    rows = []
    for i in range(n):
        if truth:
            rows.append(FrameRow(i, i / 10, 12.31 + i * 0.1, -4.02 - i / 3, 1.5708 + 1e-17 * i))
        else:
            rows.append(FrameRow(i, i / 10))
    return rows


def make_png(seed: int, width: int = WIDTH_PX, height: int = HEIGHT_PX, channels: int = 1) -> bytes:
    """A random 8-bit PNG of the given size."""
    rng = np.random.default_rng(seed)
    shape = (height, width) if channels == 1 else (height, width, channels)
    ok, buf = cv2.imencode(".png", rng.integers(0, 256, shape, dtype=np.uint8))
    assert ok
    return buf.tobytes()


def make_jpeg(seed: int, width: int = WIDTH_PX, height: int = HEIGHT_PX) -> bytes:
    rng = np.random.default_rng(seed)
    ok, buf = cv2.imencode(".jpg", rng.integers(0, 256, (height, width), dtype=np.uint8))
    assert ok
    return buf.tobytes()


def make_groundings() -> list[GroundingRow]:
    return [GroundingRow(0, 12.0, -4.0), GroundingRow(3, 12.5, -5.0)]
