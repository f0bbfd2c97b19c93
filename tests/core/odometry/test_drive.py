"""Tests of driftmap.core.odometry.drive on synthetic floors with known motion, and on KITTI when present."""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest

from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.drive import compose, dead_reckon, estimate_step, shift_horizon
from driftmap.core.odometry.params import ODOMETRY_DEFAULT, ODOMETRY_PAPER, OdometryParams
from driftmap.errors import BadInputError
from tests.floor_frames import arc_step, floor_texture, pinhole_camera, render
from tests.outside_data import SHARED_DATA

SEED = 11
D_TOL_M = 0.004  # bird's-eye travel per step
THETA_TOL_RAD = 0.0015  # bird's-eye heading change per step
LINEAR_D_TOL_M = 0.002  # linear model on a pure image translation (k_y = 0.01 m/px)
PATH_TOL_FRAC = 0.02  # dead-reckoned end-point error / distance on the synthetic floor
HORIZON_TOL_PX = 2.0  # self-calibrated horizon offset
ROTATION_CENTRE_M = 0.5  # true lever (rear axle to camera) of the drive whose drive.json says 1.5 m
LEVER_TOL_M = 0.15  # self-calibrated lever
KITTI = SHARED_DATA / "kitti"
KITTI_TARGET_FRAC = 0.05


@pytest.fixture(scope="module")
def tex() -> np.ndarray:
    return floor_texture()


START = (-1.5, 0.5, 0.4)


class TestBirdseye:
    @pytest.mark.parametrize(
        ("d", "theta"), [(0.3, 0.0), (-0.25, 0.0), (0.25, 0.04), (0.35, -0.05), (0.0, 0.03), (0.6, 0.0)]
    )
    def test_recovers_motion(self, tex: np.ndarray, d: float, theta: float) -> None:
        cam = pinhole_camera()
        step = estimate_step(
            render(tex, cam, START), render(tex, cam, arc_step(START, d, theta, cam.y_c_m)), cam
        )
        assert step.model == "homography"
        assert step.dx_m == pytest.approx(d, abs=D_TOL_M)
        assert step.dtheta_rad == pytest.approx(theta, abs=THETA_TOL_RAD)
        assert step.confidence > 0.8 and not step.stationary
        expected = arc_step((0.0, 0.0, 0.0), d, theta, cam.y_c_m)
        assert np.allclose(step.prev_T_curr, expected, atol=D_TOL_M)

    def test_a_rear_camera_reports_the_vehicles_motion(self, tex: np.ndarray) -> None:
        """forward_sign -1: the camera looks behind, so its look frame backing away is the vehicle driving
        forward, and the camera foot (behind the axle) swings the other way in a turn."""
        look = pinhole_camera()
        rear = dataclasses.replace(look, forward_sign=-1)
        d, theta = -0.3, 0.04  # rear axle arc in the look frame
        step = estimate_step(
            render(tex, look, START), render(tex, look, arc_step(START, d, theta, look.y_c_m)), rear
        )
        assert step.dx_m == pytest.approx(-d, abs=D_TOL_M)
        assert step.dtheta_rad == pytest.approx(theta, abs=THETA_TOL_RAD)
        tx, ty, turn = arc_step((0.0, 0.0, 0.0), d, theta, look.y_c_m)
        assert np.allclose(step.prev_T_curr, (-tx, -ty, turn), atol=D_TOL_M)

    def test_left_turn_is_positive_and_content_moves_right(self, tex: np.ndarray) -> None:
        cam = pinhole_camera()
        step = estimate_step(
            render(tex, cam, START), render(tex, cam, arc_step(START, 0.2, 0.05, cam.y_c_m)), cam
        )
        assert step.dtheta_rad > 0 and step.shift_px[0] > 0

    def test_stationary_is_exactly_zero(self, tex: np.ndarray) -> None:
        cam = pinhole_camera()
        frame = render(tex, cam, START)
        noise = np.random.default_rng(SEED).normal(0, 1.0, frame.shape)
        step = estimate_step(frame, np.clip(frame + noise, 0, 255).astype(np.uint8), cam)
        assert step.stationary and step.dx_m == 0.0 and step.dtheta_rad == 0.0
        assert step.prev_T_curr == (0.0, 0.0, 0.0)

    def test_low_texture_gives_low_confidence(self, tex: np.ndarray) -> None:
        cam = pinhole_camera()
        rng = np.random.default_rng(SEED)
        flat = [np.clip(100 + rng.normal(0, 0.6, (240, 320)), 0, 255).astype(np.uint8) for _ in range(2)]
        low = estimate_step(flat[0], flat[1], cam)
        high = estimate_step(
            render(tex, cam, START), render(tex, cam, arc_step(START, 0.3, 0.0, cam.y_c_m)), cam
        )
        assert low.confidence < 0.3 < 0.8 < high.confidence
        assert low.sigma_xy_m > 3 * high.sigma_xy_m and low.sigma_theta_rad > 3 * high.sigma_theta_rad

    def test_blur_lowers_confidence(self, tex: np.ndarray) -> None:
        cam = pinhole_camera()
        a, b = render(tex, cam, START), render(tex, cam, arc_step(START, 0.3, 0.0, cam.y_c_m))
        sharp = estimate_step(a, b, cam)
        blurred = estimate_step(cv2.GaussianBlur(a, (0, 0), 3.0), cv2.GaussianBlur(b, (0, 0), 3.0), cam)
        assert blurred.confidence < 0.5 * sharp.confidence

    def test_rejects_wrong_shapes(self) -> None:
        cam = pinhole_camera()
        with pytest.raises(BadInputError):
            estimate_step(np.zeros((240, 320), np.uint8), np.zeros((240, 321), np.uint8), cam)


class TestLinear:
    """The paper's model on frames that are pure image translations of a texture."""

    CAM = CameraModel(160, 120, (30, 40, 100, 60), 0.01, 0.01, 1.0, 4.0, 1)

    @staticmethod
    def frames(tex: np.ndarray, shift_px: tuple[int, int], sign: int = 1) -> tuple[np.ndarray, np.ndarray]:
        big = cv2.resize(tex[:400, :400], (200, 200), interpolation=cv2.INTER_AREA)
        y0, x0 = 40, 20
        dx, dy = shift_px[0], sign * shift_px[1]
        return big[y0 : y0 + 120, x0 : x0 + 160], big[y0 - dy : y0 - dy + 120, x0 - dx : x0 - dx + 160]

    @pytest.mark.parametrize(("shift", "sign"), [((0, 12), 1), ((0, -9), 1), ((0, 12), -1), ((5, 10), 1)])
    def test_eq_1_and_2(self, tex: np.ndarray, shift: tuple[int, int], sign: int) -> None:
        cam = dataclasses.replace(self.CAM, forward_sign=sign)
        step = estimate_step(*self.frames(tex, shift, sign), cam, ODOMETRY_PAPER)
        assert step.model == "linear"
        assert step.dx_m == pytest.approx(shift[1] * 0.01, abs=LINEAR_D_TOL_M)
        assert step.dtheta_rad == pytest.approx(math.atan(shift[0] * 0.01 / 5.0), abs=1e-3)

    def test_stationary(self, tex: np.ndarray) -> None:
        step = estimate_step(*self.frames(tex, (0, 0)), self.CAM, ODOMETRY_PAPER)
        assert step.stationary and step.dx_m == 0.0 and step.dtheta_rad == 0.0

    def test_auto_picks_linear_without_homography(self, tex: np.ndarray) -> None:
        assert estimate_step(*self.frames(tex, (0, 8)), self.CAM).model == "linear"

    def test_homography_model_needs_a_homography(self, tex: np.ndarray) -> None:
        with pytest.raises(BadInputError, match="ground_homography"):
            estimate_step(*self.frames(tex, (0, 8)), self.CAM, OdometryParams(model="homography"))


class TestDeadReckon:
    @staticmethod
    def drive(
        cam: CameraModel, truth_cam: CameraModel, tex: np.ndarray, n: int = 14
    ) -> tuple[list[tuple[float, float, float]], np.ndarray]:
        poses = [START]
        for k in range(n - 1):
            poses.append(
                arc_step(poses[-1], 0.3 + 0.08 * math.sin(1.3 * k), 0.03 * math.sin(k / 3), cam.y_c_m)
            )
        return poses, np.stack([render(tex, truth_cam, p) for p in poses])

    def test_integrates_from_the_start_pose(self, tex: np.ndarray) -> None:
        cam = pinhole_camera()
        poses, frames = self.drive(cam, cam, tex)
        run = dead_reckon(iter(frames), cam, ODOMETRY_DEFAULT, START)
        truth = np.array(poses)
        assert run.wTi.shape == (len(poses), 3) and len(run.steps) == len(poses) - 1
        assert np.allclose(run.wTi[0], START)
        distance = np.linalg.norm(np.diff(truth[:, :2], axis=0), axis=1).sum()
        assert np.linalg.norm(run.wTi[-1, :2] - truth[-1, :2]) < PATH_TOL_FRAC * distance
        assert abs(run.wTi[-1, 2] - truth[-1, 2]) < 0.01
        assert abs(run.horizon_offset_px) < HORIZON_TOL_PX

    def test_self_calibrates_a_pitch_error(self, tex: np.ndarray) -> None:
        truth_cam, cam = pinhole_camera(35.0), pinhole_camera(34.0)  # calibration off by 1 degree
        true_offset = 250.0 * math.tan(math.radians(1.0))
        poses, frames = self.drive(cam, truth_cam, tex, n=16)
        truth = np.array(poses)
        distance = np.linalg.norm(np.diff(truth[:, :2], axis=0), axis=1).sum()
        raw = dead_reckon(frames, cam, dataclasses.replace(ODOMETRY_DEFAULT, self_calibrate=False), START)
        cal = dead_reckon(frames, cam, ODOMETRY_DEFAULT, START)
        assert cal.horizon_offset_px == pytest.approx(true_offset, abs=HORIZON_TOL_PX)
        err_raw = np.linalg.norm(raw.wTi[-1, :2] - truth[-1, :2])
        err_cal = np.linalg.norm(cal.wTi[-1, :2] - truth[-1, :2])
        assert err_cal < 0.5 * err_raw and err_cal < PATH_TOL_FRAC * distance

    def test_self_calibrates_the_rotation_centre(self, tex: np.ndarray) -> None:
        """The vehicle turns about a point 0.5 m behind the camera, drive.json says 1.5 m (slip, another
        vehicle): the fixed lever under-reads every turn; the fitted one follows the floor's rotation."""
        cam = pinhole_camera()
        start = (-4.0, -1.5, 0.3)  # 6 m of S-bends that stay on the texture
        poses = [start]
        for k in range(24):
            poses.append(arc_step(poses[-1], 0.25, 0.05 * math.sin(k / 3), ROTATION_CENTRE_M))
        frames = np.stack([render(tex, cam, p) for p in poses])
        truth = np.array(poses)
        distance = np.linalg.norm(np.diff(truth[:, :2], axis=0), axis=1).sum()
        fixed = dead_reckon(frames, cam, dataclasses.replace(ODOMETRY_DEFAULT, calibrate_lever=False), start)
        fitted = dead_reckon(frames, cam, ODOMETRY_DEFAULT, start)
        assert fixed.lever_m == cam.y_c_m
        assert fitted.lever_m == pytest.approx(ROTATION_CENTRE_M, abs=LEVER_TOL_M)
        err_fixed = np.linalg.norm(fixed.wTi[-1, :2] - truth[-1, :2])
        err_fitted = np.linalg.norm(fitted.wTi[-1, :2] - truth[-1, :2])
        assert err_fitted < 0.5 * err_fixed and err_fitted < PATH_TOL_FRAC * distance

    def test_no_frames(self) -> None:
        assert dead_reckon([], pinhole_camera()).wTi.shape == (0, 3)


class TestGeometry:
    def test_compose(self) -> None:
        out = compose((1.0, 2.0, math.pi / 2), (1.0, 0.5, math.pi))
        assert np.allclose(out, [0.5, 3.0, -math.pi / 2])

    def test_shift_horizon_moves_the_floor(self) -> None:
        cam = pinhole_camera()
        moved = shift_horizon(cam, 5.0)
        u, v = 160.0, 175.0
        a = np.asarray(moved.homography()) @ [u, v, 1]
        b = np.asarray(cam.homography()) @ [u, v + 5.0, 1]
        assert np.allclose(a[:2] / a[2], b[:2] / b[2])
        assert moved.k_y_m_per_px != cam.k_y_m_per_px


@pytest.mark.skipif(not KITTI.is_dir(), reason="shared KITTI clips absent (../shared/data beside the repo)")
class TestKitti:
    @staticmethod
    def run(name: str) -> float:
        from driftmap.formats.drive_folder import read_drive_folder
        from driftmap.formats.frame_images import decode_gray

        drive = read_drive_folder(KITTI / name)
        truth = np.array([[r.x_m, r.y_m, r.yaw_rad] for r in drive.frames], dtype=np.float64)
        frames = (decode_gray(f.read_bytes(), f) for f in drive.frame_files)
        run = dead_reckon(frames, drive.meta.camera, ODOMETRY_DEFAULT, tuple(truth[0]))
        distance = float(np.linalg.norm(np.diff(truth[:, :2], axis=0), axis=1).sum())
        return float(np.linalg.norm(run.wTi[-1, :2] - truth[-1, :2])) / distance

    def test_clip_1_within_target(self) -> None:
        assert self.run("kitti-clip-1") < KITTI_TARGET_FRAC

    def test_clip_2_within_target(self) -> None:
        """Clip 2 (a 98 degree right turn up a ramp): 2.5 % (12.5 % with the fixed rotation centre and no
        motion prior, 5.4 % with one horizon for the whole drive).

        Per step against the ground truth: the fixed lever y_c = 1.0 m under-read every turn step by ~7 %
        (0.14 rad short after the turn; ground-truth translations with our headings alone end 8.1 % off),
        while the floor's own near-far rotation matched the truth (-1.738 vs -1.709 rad); the fitted
        rotation centre (~0.25 m) removes it. At step 40 the coarse search picked a false minimum (lane
        lines along the motion: 0.17 m instead of 1.13 m) that the descent from the previous step's shift
        beats (cost 0.116 against 0.375). The camera's pitch to the road ahead drifts by ~25 px of horizon
        along the ramp (per-step estimates ~30 px at the start, ~5 px at the end; one median for the drive
        read the first steps 25-36 % long and the last ~10 % short, 6.1 % with true headings): the tracked
        horizon (core/odometry/pitch) follows it where it leaves the drive's level by > 3 standard errors (3.1 %
        with true headings). Step 38 still fails at the edge of the search range (+0.53 m).
        """
        assert self.run("kitti-clip-2") < KITTI_TARGET_FRAC
