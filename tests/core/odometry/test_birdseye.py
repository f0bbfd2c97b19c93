"""Tests of driftmap.core.odometry.birdseye: a floor pattern of known size seen through a known homography
shows at its size and place in the bird's-eye view; ROIs above the horizon and singular homographies are
refused."""

from __future__ import annotations

import numpy as np
import pytest

from driftmap.core.odometry.birdseye import birdseye_view, roi_footprint
from driftmap.core.odometry.grid import apply_homography
from driftmap.errors import BadInputError
from tests.floor_frames import PATCH_M, patch_frame, pinhole_camera

SIZE_TOL_M = 0.02  # the patch's sides in the view: two view pixels (1 cm here)
PLACE_TOL_M = 0.01  # the patch's centre
# a camera whose horizon is the image row v = 40 (pixel -> floor: x = 600 / (v - 40), y = 3 (160 - u) / (v - 40))
LOW_HORIZON = np.array([[0.0, 0.0, 600.0], [-3.0, 0.0, 480.0], [0.0, 1.0, -40.0]])


class TestBirdsEye:
    def test_a_floor_patch_shows_at_its_size_and_place(self) -> None:
        camera = pinhole_camera()
        hom = np.asarray(camera.homography())
        view = birdseye_view(patch_frame(hom, (320, 240)), hom, camera.ground_roi_px)
        assert max(view.image.shape) <= 400 and view.res_m_per_px * 1000 == round(view.res_m_per_px * 1000)
        rows, cols = np.nonzero(view.image > 145)  # half-way between floor and patch
        top_left = view.floor_from_px @ [cols.min() - 0.5, rows.min() - 0.5, 1.0]
        bottom_right = view.floor_from_px @ [cols.max() + 0.5, rows.max() + 0.5, 1.0]
        # x (the way the camera looks) points up the image, y (left) to the left
        (x0, x1), (y0, y1) = PATCH_M
        assert np.allclose(top_left[:2], [x1, y1], atol=SIZE_TOL_M)
        assert np.allclose(bottom_right[:2], [x0, y0], atol=SIZE_TOL_M)
        centre = view.floor_from_px @ [cols.mean(), rows.mean(), 1.0]
        assert np.allclose(centre[:2], [(x0 + x1) / 2, (y0 + y1) / 2], atol=PLACE_TOL_M)
        # the footprint is the ROI's corners on the floor, placed in the view
        x, y, w, h = camera.ground_roi_px
        corners = np.array([[x, y], [x + w, y], [x + w, y + h], [x, y + h]], dtype=np.float64)
        assert np.allclose(view.footprint_m, apply_homography(hom, corners))
        assert np.allclose(apply_homography(view.floor_from_px, view.footprint_px), view.footprint_m)
        (xr, yr) = view.ranges_m()
        assert xr[0] < view.footprint_m[:, 0].min() and view.footprint_m[:, 0].max() < xr[1]
        assert yr[0] < view.footprint_m[:, 1].min() and view.footprint_m[:, 1].max() < yr[1]

    def test_floor_behind_the_camera_is_black(self) -> None:
        frame = np.full((240, 320), 200, np.uint8)
        view = birdseye_view(frame, LOW_HORIZON, (0, 60, 320, 180), margin=2.0)
        x_near = view.floor_from_px @ [0.0, view.image.shape[0] - 1.0, 1.0]
        assert x_near[0] < 0 and view.image[-1].max() == 0  # x < 0 lies behind the camera

    def test_an_roi_above_the_horizon_is_refused(self) -> None:
        with pytest.raises(BadInputError, match="horizon") as err:
            roi_footprint(LOW_HORIZON, (8, 20, 300, 100))
        assert err.value.field == "ground_roi"
        with pytest.raises(BadInputError) as err:
            birdseye_view(np.zeros((240, 320), np.uint8), LOW_HORIZON, (8, 20, 300, 100))
        assert err.value.field == "ground_roi"

    def test_a_singular_homography_is_refused(self) -> None:
        flat = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
        with pytest.raises(BadInputError, match="singular") as err:
            birdseye_view(np.zeros((240, 320), np.uint8), flat, (8, 100, 300, 100))
        assert err.value.field == "ground_homography"
