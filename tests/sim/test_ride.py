"""Ride bounce, motion blur and calibration error of the simulated camera."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from driftmap.formats.drive_folder import read_drive_folder
from driftmap.sim.ride import (
    RIDE_DEFAULT,
    RIDE_NONE,
    RideParams,
    apply_ride,
    calibrated_rig,
    floor_px_per_m,
    ride_motion,
)
from driftmap.sim.rig import CameraRig
from driftmap.sim.site import simulate_site


def _warp_of(rig: CameraRig, pitch: float, roll: float, yaw: float, uv: tuple[float, float]) -> np.ndarray:
    """Where apply_ride moves one bright pixel, found as the intensity centroid of the warped image."""
    img = np.zeros((rig.params.height_px, rig.params.width_px), np.uint8)
    img[int(uv[1]), int(uv[0])] = 255
    out = apply_ride(img, rig, pitch, roll, yaw, 0.0).astype(np.float64)
    v, u = np.nonzero(out)
    w = out[v, u]
    return np.array([np.sum(u * w), np.sum(v * w)]) / np.sum(w)


class TestRotationWarp:
    def test_no_motion_is_identity(self) -> None:
        img = np.random.default_rng(1).integers(0, 256, (240, 320), dtype=np.uint8)
        assert np.array_equal(apply_ride(img, CameraRig(), 0.0, 0.0, 0.0, 0.0), img)

    def test_pitch_matches_a_camera_mounted_lower(self) -> None:
        rig, delta = CameraRig(), math.radians(1.0)
        pitched = CameraRig(replace(rig.params, pitch_rad=rig.params.pitch_rad + delta))
        uv = (200.0, 190.0)
        floor = rig.pixel_to_floor(np.array([uv[0]]), np.array([uv[1]]))
        expected = pitched.floor_to_pixel(floor)[0]
        assert np.allclose(_warp_of(rig, delta, 0.0, 0.0, uv), expected, atol=0.3)

    def test_yaw_left_moves_the_scene_right_by_f_tan(self) -> None:
        rig, delta = CameraRig(), math.radians(1.0)
        uv = (160.0, 120.0)
        moved = _warp_of(rig, 0.0, 0.0, delta, uv)
        assert moved[0] - uv[0] == pytest.approx(rig.params.focal_px * math.tan(delta), abs=0.3)


class TestMotionBlur:
    def test_blur_keeps_mean_brightness_and_streaks_vertically(self) -> None:
        img = np.zeros((240, 320), np.uint8)
        img[100:140, 100:220] = 200
        out = apply_ride(img, CameraRig(), 0.0, 0.0, 0.0, 6.0)
        assert out.mean() == pytest.approx(img.mean(), rel=0.01)
        assert np.array_equal(out[:, 50], img[:, 50])  # columns without an edge stay put
        assert (out[140:143, 150] > 0).all() and (out[97:100, 150] < 200).all()  # a streak across each edge

    def test_floor_px_per_m_is_the_roi_centre_scale(self) -> None:
        rig = CameraRig()
        assert 1.0 / floor_px_per_m(rig) == pytest.approx(rig.camera_model.k_y_m_per_px, rel=0.05)


class TestRideMotion:
    def test_amplitude_follows_speed_and_yaw_is_constant(self) -> None:
        t = np.arange(0.0, 600.0, 0.1)
        fast = ride_motion(t, np.full(t.shape, 5.0), np.random.default_rng(3), RIDE_DEFAULT)
        still = ride_motion(t, np.zeros(t.shape), np.random.default_rng(3), RIDE_DEFAULT)
        assert fast.shape == (len(t), 3)
        assert np.std(fast[:, 0]) == pytest.approx(RIDE_DEFAULT.pitch_bounce_rad, rel=0.35)
        assert np.std(still[:, 1]) == pytest.approx(0.25 * np.std(fast[:, 1]), rel=1e-9)
        assert np.ptp(fast[:, 2]) == 0.0

    def test_none_means_a_perfect_rig(self) -> None:
        t = np.arange(0.0, 10.0, 0.1)
        assert not ride_motion(t, np.full(t.shape, 5.0), np.random.default_rng(0), RIDE_NONE).any()
        rig = CameraRig()
        assert calibrated_rig(rig, np.random.default_rng(0), RIDE_NONE).camera_model == rig.camera_model

    def test_calibration_error_changes_scale_by_about_the_height_error(self) -> None:
        rig = CameraRig()
        params = RideParams(height_error_frac=0.02, pitch_error_rad=0.0)
        ratios = [
            calibrated_rig(rig, np.random.default_rng(s), params).camera_model.k_y_m_per_px
            / rig.camera_model.k_y_m_per_px
            for s in range(200)
        ]
        assert np.std(ratios) == pytest.approx(0.02, rel=0.25)


class TestSimulatedSite:
    def test_each_drive_carries_its_own_imperfect_calibration(self, tmp_path: Path) -> None:
        simulate_site(
            tmp_path / "s", seed=4, size="tiny", obscurants=False, max_frames_per_drive=3, workers=1
        )
        nominal = CameraRig().camera_model
        cameras = [read_drive_folder(d).meta.camera for d in sorted((tmp_path / "s" / "drives").iterdir())]
        scales = [c.k_y_m_per_px / nominal.k_y_m_per_px for c in cameras]
        assert len(set(scales)) == len(cameras)  # no two drives calibrated alike
        assert all(abs(s - 1.0) < 5 * RIDE_DEFAULT.height_error_frac + 0.02 for s in scales)
