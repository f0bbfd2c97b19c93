"""Odometry through a lens: frames recorded by a distorting camera, undistorted over the grid's window."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from driftmap.core.imaging.lens import Lens, undistort_points
from driftmap.core.odometry.drive import estimate_step
from driftmap.core.odometry.grid import match_grid, prepare_frame
from driftmap.core.odometry.params import ODOMETRY_DEFAULT
from tests.floor_frames import arc_step, floor_texture, pinhole_camera, render

D_TOL_M = 0.004  # as the bird's-eye tests of test_drive.py
THETA_TOL_RAD = 0.0015
K = ((250.0, 0.0, 160.0), (0.0, 250.0, 120.0), (0.0, 0.0, 1.0))  # pinhole_camera's intrinsics
LENSES = [
    Lens("pinhole", K, (-0.3, 0.1, 0.001, -0.001, 0.0)),
    Lens("fisheye", K, (0.05, -0.02, 0.0, 0.0)),
]
START = (-1.5, 0.5, 0.4)


def _through(lens: Lens, ideal: np.ndarray) -> np.ndarray:
    """What the real camera records: each raw pixel samples the ideal image at its undistorted position."""
    h, w = ideal.shape
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    q = undistort_points(lens, np.stack([uu.ravel(), vv.ravel()], axis=1)).reshape(h, w, 2).astype(np.float32)
    return np.asarray(cv2.remap(ideal, q[..., 0], q[..., 1], cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT))


@pytest.fixture(scope="module")
def tex() -> np.ndarray:
    return floor_texture()


class TestLensOdometry:
    @pytest.mark.parametrize("lens", LENSES, ids=["pinhole", "fisheye"])
    @pytest.mark.parametrize(("d", "theta"), [(0.3, 0.0), (0.35, -0.05)])
    def test_recovers_motion_through_the_lens(
        self, tex: np.ndarray, lens: Lens, d: float, theta: float
    ) -> None:
        ideal_cam = pinhole_camera()
        cam = dataclasses.replace(ideal_cam, lens=lens)
        a = _through(lens, render(tex, ideal_cam, START))
        b = _through(lens, render(tex, ideal_cam, arc_step(START, d, theta, cam.y_c_m)))
        step = estimate_step(a, b, cam)
        assert step.dx_m == pytest.approx(d, abs=D_TOL_M)
        assert step.dtheta_rad == pytest.approx(theta, abs=THETA_TOL_RAD)
        assert step.confidence > 0.8

    def test_without_the_lens_the_raw_frames_mislead(self, tex: np.ndarray) -> None:
        cam = pinhole_camera()
        lens = LENSES[0]
        a = _through(lens, render(tex, cam, START))
        b = _through(lens, render(tex, cam, arc_step(START, 0.35, 0.0, cam.y_c_m)))
        assert abs(estimate_step(a, b, cam).dx_m - 0.35) > D_TOL_M

    def test_tables_only_with_a_lens_and_over_a_window(self) -> None:
        cam = pinhole_camera()
        assert match_grid(cam, ODOMETRY_DEFAULT).undistort is None
        tables = match_grid(dataclasses.replace(cam, lens=LENSES[0]), ODOMETRY_DEFAULT).undistort
        assert tables is not None
        x, y, w, h = tables.window
        rx, ry, rw, rh = cam.ground_roi_px
        assert x <= rx and y <= ry and x + w >= rx + rw and y + h >= ry + rh

    def test_the_recorded_frame_is_kept_for_a_restart(self, tex: np.ndarray) -> None:
        cam = dataclasses.replace(pinhole_camera(), lens=LENSES[1])
        frame = _through(LENSES[1], render(tex, pinhole_camera(), START))
        prepared = prepare_frame(frame, cam, match_grid(cam, ODOMETRY_DEFAULT), ODOMETRY_DEFAULT)
        assert prepared.recorded_frame() is frame and not np.array_equal(prepared.raw, frame)
