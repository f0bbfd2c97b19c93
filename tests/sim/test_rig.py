"""The camera block computed from the simulated pinhole geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from driftmap.sim.rig import CameraRig

PIXEL_TOL = 1e-6


@pytest.fixture(scope="module")
def rig() -> CameraRig:
    return CameraRig()


class TestHomography:
    def test_roi_centre_maps_to_y_h_straight_ahead(self, rig: CameraRig) -> None:
        cam = rig.camera_model
        x, y, w, h = cam.ground_roi_px
        H = cam.homography()
        assert H is not None
        q = H @ np.array([x + (w - 1) / 2, y + (h - 1) / 2, 1.0])
        assert q[2] > 0
        assert q[0] / q[2] == pytest.approx(cam.y_h_m, abs=1e-9)
        assert q[1] / q[2] == pytest.approx(0.0, abs=1e-9)

    def test_round_trip(self, rig: CameraRig) -> None:
        u, v = np.meshgrid(np.arange(0, 320, 17.0), np.arange(130, 240, 11.0))
        back = rig.floor_to_pixel(rig.pixel_to_floor(u, v))
        assert np.allclose(back[..., 0], u, atol=PIXEL_TOL) and np.allclose(back[..., 1], v, atol=PIXEL_TOL)

    def test_matches_the_pinhole(self, rig: CameraRig) -> None:
        """Project a floor point with the pinhole (K, pitch, height) and compare with H^-1."""
        p = rig.params
        point_f = np.array([3.0, 0.7, 0.0])
        centre_f = np.array([0.0, 0.0, p.height_m])
        ray_c = rig.fRc.T @ (point_f - centre_f)
        uv = (rig.K @ ray_c)[:2] / ray_c[2]
        assert np.allclose(rig.floor_to_pixel(point_f[:2]), uv, atol=PIXEL_TOL)

    def test_left_is_left_and_near_is_low(self, rig: CameraRig) -> None:
        left = rig.floor_to_pixel(np.array([3.0, 1.0]))
        right = rig.floor_to_pixel(np.array([3.0, -1.0]))
        near = rig.floor_to_pixel(np.array([2.0, 0.0]))
        assert left[0] < right[0] and near[1] > left[1]


class TestCameraBlock:
    def test_k_values_are_metres_per_pixel_at_the_roi_centre(self, rig: CameraRig) -> None:
        cam = rig.camera_model
        x, y, w, h = cam.ground_roi_px
        uc, vc = x + (w - 1) / 2, y + (h - 1) / 2
        a, b = rig.pixel_to_floor(np.array([uc, uc]), np.array([vc - 2.0, vc + 2.0]))
        assert abs(a[0] - b[0]) / 4 == pytest.approx(cam.k_y_m_per_px, rel=0.01)
        a, b = rig.pixel_to_floor(np.array([uc - 2.0, uc + 2.0]), np.array([vc, vc]))
        assert abs(a[1] - b[1]) / 4 == pytest.approx(cam.k_x_m_per_px, rel=0.01)
        assert cam.forward_sign == 1 and cam.y_c_m == rig.params.y_c_m

    def test_roi_sees_only_floor_in_a_5m_tunnel(self, rig: CameraRig) -> None:
        p = rig.params
        x, y, w, h = rig.camera_model.ground_roi_px
        assert y + h <= p.height_px and x >= 0 and x + w <= p.width_px
        assert x + w / 2 == pytest.approx(p.width_px / 2, abs=1.0)  # bottom centre
        uu, vv = np.meshgrid(np.arange(x, x + w, dtype=float), np.arange(y, y + h, dtype=float))
        xy = rig.pixel_to_floor(uu, vv)
        assert np.all(np.isfinite(xy)) and np.all(xy[..., 0] > 0)
        for yaw in (-p.max_yaw_dev_rad, p.max_yaw_dev_rad):
            lateral = xy[..., 0] * math.sin(yaw) + xy[..., 1] * math.cos(yaw)
            assert np.max(np.abs(lateral)) + p.max_offset_m <= 2.5 + 1e-9

    def test_roi_is_as_wide_as_allowed(self, rig: CameraRig) -> None:
        assert rig.camera_model.ground_roi_px[2] >= 80
