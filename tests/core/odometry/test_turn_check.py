"""Tests of driftmap.core.odometry.turn_check: forward_sign, the turn's direction and the lever y_c from a
rendered drive that goes straight and then turns about a point 0.5 m behind the camera (drive.json: 1.5 m)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.drive import MatchedSteps, match_frames
from driftmap.core.odometry.params import ODOMETRY_DEFAULT
from driftmap.core.odometry.turn_check import check_turn, lever_for_turn, mount_camera
from driftmap.errors import BadInputError
from tests.floor_frames import arc_step, floor_texture, pinhole_camera, render

TRUE_Y_C_M = 0.5  # where the vehicle turns about; the camera says 1.5 m
Y_C_TOL_M = 0.15  # as the self-calibration's own test
TURN_RAD = 18 * 0.045  # 46 degrees, left
TURN_TOL_FRAC = 0.05


def straight_then_turn(turn_per_step: float = 0.045) -> np.ndarray:
    """(25, 240, 320) uint8 frames: 6 steps of 0.25 m straight, then 18 turning ``turn_per_step`` each."""
    tex, cam = floor_texture(), pinhole_camera()
    poses = [(-4.0, -1.5, 0.3)]
    for k in range(24):
        poses.append(arc_step(poses[-1], 0.25, 0.0 if k < 6 else turn_per_step, TRUE_Y_C_M))
    return np.stack([render(tex, cam, p) for p in poses])


def mirrored(camera: CameraModel) -> CameraModel:
    """The camera with its ground plane fitted to floor y measured to the right instead of the left."""
    hom = np.diag([1.0, -1.0, 1.0]) @ np.asarray(camera.homography())
    return dataclasses.replace(camera, ground_homography=tuple(tuple(float(v) for v in row) for row in hom))


@pytest.fixture(scope="module")
def frames() -> np.ndarray:
    return straight_then_turn()


@pytest.fixture(scope="module")
def matched(frames: np.ndarray) -> MatchedSteps:
    return match_frames(frames, pinhole_camera())


class TestCheckTurn:
    def test_a_good_mounting_and_the_lever(self, matched: MatchedSteps) -> None:
        cam = pinhole_camera()
        result = check_turn(matched, cam, math.radians(45.0))
        assert not result.sign_wrong and not result.direction_wrong
        assert result.travelled_m == pytest.approx(6.0, rel=0.03)
        assert result.turned_rad == pytest.approx(TURN_RAD, rel=TURN_TOL_FRAC)
        assert result.turn_ratio == pytest.approx(TURN_RAD / math.radians(45.0), rel=TURN_TOL_FRAC)
        assert result.configured_y_c_m == 1.5
        assert result.fitted_y_c_m == pytest.approx(TRUE_Y_C_M, abs=Y_C_TOL_M)
        assert result.fitted_se_m is not None and 0 < result.fitted_se_m < Y_C_TOL_M
        fixed = mount_camera(cam, result)
        assert fixed.y_c_m == result.y_c_m == result.fitted_y_c_m and fixed.forward_sign == cam.forward_sign

    @pytest.mark.parametrize("configured_m", [0.0, 1.5, 3.0])
    def test_the_lever_that_turns_through_the_stated_angle(
        self, frames: np.ndarray, configured_m: float
    ) -> None:
        """Told the true turn, whatever lever the camera starts from; the fit off (as for a short region)."""
        cam = dataclasses.replace(pinhole_camera(), y_c_m=configured_m)
        lever = lever_for_turn(match_frames(frames, cam), cam, TURN_RAD)
        assert lever == pytest.approx(TRUE_Y_C_M, abs=Y_C_TOL_M)
        assert lever_for_turn(match_frames(frames, cam), cam, 1.6 * TURN_RAD) is not None  # a shorter lever
        assert lever_for_turn(match_frames(frames, cam), cam, 0.2 * TURN_RAD) is None  # none within 5 m

    def test_the_stated_lever_is_used_when_the_floor_does_not_fit_one(self, matched: MatchedSteps) -> None:
        cam = pinhole_camera()
        no_fit = dataclasses.replace(ODOMETRY_DEFAULT, calibrate_lever=False)
        result = check_turn(matched, cam, TURN_RAD, no_fit)
        assert result.fitted_y_c_m is None and result.fitted_se_m is None
        assert result.turn_y_c_m == pytest.approx(TRUE_Y_C_M, abs=Y_C_TOL_M)
        assert mount_camera(cam, result).y_c_m == result.turn_y_c_m

    def test_without_the_birdseye_model_no_lever_is_found(self, frames: np.ndarray) -> None:
        cam = dataclasses.replace(pinhole_camera(), ground_homography=None)  # the linear model
        no_fit = dataclasses.replace(ODOMETRY_DEFAULT, calibrate_lever=False)
        result = check_turn(match_frames(frames, cam), cam, TURN_RAD, no_fit)
        assert result.turn_y_c_m is None and result.fitted_y_c_m is None
        assert mount_camera(cam, result).y_c_m == cam.y_c_m

    def test_a_mirrored_ground_plane_turns_the_wrong_way(self, frames: np.ndarray) -> None:
        cam = mirrored(pinhole_camera())
        result = check_turn(match_frames(frames, cam), cam, math.radians(45.0))
        assert result.direction_wrong and result.turn_ratio < 0 and not result.sign_wrong
        assert result.turn_y_c_m is None
        with pytest.raises(BadInputError, match="mirrored") as err:
            mount_camera(cam, result)
        assert err.value.field == "turn_deg"

    def test_a_wrong_forward_sign(self, frames: np.ndarray) -> None:
        cam = dataclasses.replace(pinhole_camera(), forward_sign=-1)
        steps = match_frames(frames, cam)
        result = check_turn(steps, cam, math.radians(45.0))
        assert result.sign_wrong and result.travelled_m < 0
        assert mount_camera(cam, result).forward_sign == 1
        assert not check_turn(steps, cam, math.radians(45.0), reverse=True).sign_wrong

    @pytest.mark.parametrize("turn_deg", [10.0, math.nan])
    def test_a_turn_too_small_to_check(self, matched: MatchedSteps, turn_deg: float) -> None:
        with pytest.raises(BadInputError) as err:
            check_turn(matched, pinhole_camera(), math.radians(turn_deg))
        assert err.value.field == "turn_deg"

    def test_a_drive_that_does_not_turn(self) -> None:
        cam = pinhole_camera()
        with pytest.raises(BadInputError, match="no usable turn") as err:
            check_turn(match_frames(straight_then_turn(0.0), cam), cam, math.radians(45.0))
        assert err.value.field == "drive"
