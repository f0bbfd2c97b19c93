"""Tests of driftmap.core.imaging.lens: the two lens models, point mapping and windowed remap tables."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from driftmap.core.imaging.lens import (
    Lens,
    LensMaps,
    distort_points,
    lens_maps,
    undistort_image,
    undistort_points,
)
from driftmap.errors import BadInputError
from tests.core.imaging.boards import FISHEYE, PINHOLE, SIZE, board_poses, render_view

POINT_TOL_PX = 1e-3  # distort then undistort returns the pixel
OPENCV_MEAN_TOL = 0.05  # grey levels: whole-frame undistortion vs OpenCV's with the same K (fixed-point maps)
REMAP_MEAN_TOL = (
    6.0  # grey levels: undistorted view vs the ideal pinhole view (edges differ by interpolation)
)


class TestLensValues:
    @pytest.mark.parametrize(
        ("kwargs", "field"),
        [
            ({"model": "kannala"}, "lens.model"),
            ({"K": ((1.0, 0.0, 1.0), (0.0, 1.0, 1.0))}, "lens.K"),
            ({"K": ((-5.0, 0.0, 1.0), (0.0, 5.0, 1.0), (0.0, 0.0, 1.0))}, "lens.K"),
            ({"distortion": (0.1, 0.2, 0.3)}, "lens.distortion"),
            ({"distortion": (0.1, float("nan"), 0.0, 0.0)}, "lens.distortion"),
        ],
    )
    def test_bad_values_name_the_field(self, kwargs: dict[str, object], field: str) -> None:
        values: dict[str, object] = {"model": "pinhole", "K": PINHOLE.K, "distortion": (0.0, 0.0, 0.0, 0.0)}
        values.update(kwargs)
        with pytest.raises(BadInputError) as err:
            Lens(**values)  # type: ignore[arg-type]
        assert err.value.field == field

    def test_fisheye_takes_four_coefficients(self) -> None:
        with pytest.raises(BadInputError, match="k1 k2 k3 k4"):
            Lens("fisheye", FISHEYE.K, (0.0, 0.0, 0.0, 0.0, 0.0))


class TestPoints:
    @pytest.mark.parametrize("lens", [PINHOLE, FISHEYE], ids=["pinhole", "fisheye"])
    def test_round_trip(self, lens: Lens) -> None:
        rng = np.random.default_rng(5)
        ideal = rng.uniform([100, 80], [540, 400], size=(200, 2))
        back = undistort_points(lens, distort_points(lens, ideal))
        assert np.abs(back - ideal).max() < POINT_TOL_PX

    def test_principal_point_is_fixed(self) -> None:
        centre = np.array([[PINHOLE.K[0][2], PINHOLE.K[1][2]]])
        assert np.allclose(distort_points(PINHOLE, centre), centre)

    def test_shape_is_checked(self) -> None:
        with pytest.raises(BadInputError, match="points_px"):
            undistort_points(PINHOLE, np.zeros((3, 3)))


class TestMaps:
    @pytest.mark.parametrize("lens", [PINHOLE, FISHEYE], ids=["pinhole", "fisheye"])
    def test_undistorted_view_is_the_ideal_view(self, lens: Lens) -> None:
        ideal = Lens("pinhole", lens.K, (0.0, 0.0, 0.0, 0.0))
        rvec, tvec = board_poses(1, 0.45 if lens.model == "pinhole" else 0.3, seed=8)[0]
        window = (200, 150, 240, 180)
        out = LensMaps(lens, SIZE, window).apply(render_view(lens, rvec, tvec, ss=2))
        truth = render_view(ideal, rvec, tvec, ss=2)
        x, y, w, h = window
        diff = np.abs(out[y : y + h, x : x + w].astype(float) - truth[y : y + h, x : x + w])
        assert diff.mean() < REMAP_MEAN_TOL
        assert out.shape == truth.shape
        assert np.all(out[:y, x : x + w] == out[y, x : x + w])  # outside: the window's edge replicated

    def test_window_must_fit(self) -> None:
        with pytest.raises(BadInputError, match="window"):
            LensMaps(PINHOLE, SIZE, (600, 0, 100, 10))

    def test_tables_are_built_once(self) -> None:
        assert lens_maps(PINHOLE, SIZE, (0, 0, 64, 48)) is lens_maps(PINHOLE, SIZE, (0, 0, 64, 48))


class TestUndistortImage:
    @pytest.mark.parametrize("lens", [PINHOLE, FISHEYE], ids=["pinhole", "fisheye"])
    def test_is_opencvs_undistortion_keeping_k(self, lens: Lens) -> None:
        rng = np.random.default_rng(3)
        noise = cv2.GaussianBlur(rng.normal(0.0, 1.0, SIZE[::-1]).astype(np.float32), (0, 0), 2.0)
        frame = np.clip(128 + 60 * noise / noise.std(), 0, 255).astype(np.uint8)
        k, d = lens.matrix(), lens.coeffs()
        if lens.model == "fisheye":
            truth = cv2.fisheye.undistortImage(frame, k, d, Knew=k)
        else:
            truth = cv2.undistort(frame, k, d, newCameraMatrix=k)
        out = undistort_image(lens, frame)
        uu, vv = np.meshgrid(np.arange(SIZE[0], dtype=np.float64), np.arange(SIZE[1], dtype=np.float64))
        raw = distort_points(lens, np.stack([uu.ravel(), vv.ravel()], axis=1)).reshape(SIZE[1], SIZE[0], 2)
        inside = np.all((raw >= 1) & (raw <= np.array(SIZE) - 2), axis=2)  # OpenCV fills the rest with 0
        assert out.shape == frame.shape and out.dtype == np.uint8
        assert inside.mean() > 0.8
        assert np.abs(out.astype(float) - truth)[inside].mean() < OPENCV_MEAN_TOL

    def test_takes_grey_frames_only(self) -> None:
        with pytest.raises(BadInputError, match="frame"):
            undistort_image(PINHOLE, np.zeros((48, 64, 3), np.uint8))
