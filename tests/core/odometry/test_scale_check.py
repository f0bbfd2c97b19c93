"""Tests of driftmap.core.odometry.scale_check: floor scale and forward_sign from a measured straight drive."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from driftmap.core.odometry.drive import dead_reckon
from driftmap.core.odometry.scale_check import check_scale, scale_camera
from driftmap.errors import BadInputError
from tests.floor_frames import arc_step, floor_texture, pinhole_camera, render

RATIO_TOL = 0.01  # recovered scale factor on rendered frames
WRONG = 1.08  # the calibration's floor lengths are 8 % too long


def straight_frames(n: int = 9, step_m: float = 0.25, sign: float = 1.0) -> list[np.ndarray]:
    tex, cam = floor_texture(), pinhole_camera()
    pose = (-1.0, 0.3, 0.2)
    frames = []
    for _ in range(n):
        frames.append(render(tex, cam, pose))
        pose = arc_step(pose, sign * step_m, 0.0, cam.y_c_m)
    return frames


class TestCheck:
    def test_ratio_and_sign_from_poses(self) -> None:
        poses = np.array([[0.0, 0.0, np.pi / 2], [0.0, 1.0, np.pi / 2], [0.1, 2.5, np.pi / 2]])
        result = check_scale(poses, 2.0)
        assert result.travelled_m == pytest.approx(2.5) and result.ratio == pytest.approx(0.8)
        assert not result.sign_wrong
        assert check_scale(poses, 2.0, reverse=True).sign_wrong

    def test_a_wrong_scale_is_found_and_fixed(self) -> None:
        truth = pinhole_camera()
        wrong = scale_camera(truth, WRONG)
        result = check_scale(dead_reckon(straight_frames(), wrong).wTi, 2.0)
        assert not result.sign_wrong
        assert result.ratio == pytest.approx(1 / WRONG, rel=RATIO_TOL)
        fixed = scale_camera(wrong, result.ratio)
        assert fixed.k_x_m_per_px == pytest.approx(truth.k_x_m_per_px, rel=RATIO_TOL)
        assert fixed.y_h_m == pytest.approx(truth.y_h_m, rel=RATIO_TOL)
        assert np.allclose(fixed.homography(), truth.homography(), rtol=RATIO_TOL, atol=1e-9)

    def test_a_wrong_forward_sign_is_found(self) -> None:
        wrong = dataclasses.replace(pinhole_camera(), forward_sign=-1, ground_homography=None)  # linear model
        result = check_scale(dead_reckon(straight_frames(), wrong).wTi, 2.0)
        assert result.sign_wrong and result.travelled_m < 0
        assert scale_camera(wrong, result.ratio, flip_sign=True).forward_sign == 1

    @pytest.mark.parametrize(
        ("poses", "distance", "field"),
        [
            (np.zeros((1, 3)), 1.0, "wTi"),
            (np.zeros((3, 3)), 0.0, "distance_m"),
            (np.zeros((3, 3)), 1.0, "drive"),
        ],
    )
    def test_bad_input(self, poses: np.ndarray, distance: float, field: str) -> None:
        with pytest.raises(BadInputError) as err:
            check_scale(poses, distance)
        assert err.value.field == field

    def test_scale_must_be_positive(self) -> None:
        with pytest.raises(BadInputError, match="positive"):
            scale_camera(pinhole_camera(), -1.0)
