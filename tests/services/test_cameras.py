"""Tests of driftmap.services.cameras: calibration on rendered boards and known floor points, and camera
profiles on a real database."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.core.imaging.calibration import Board
from driftmap.core.odometry.grid import apply_homography
from driftmap.errors import BadInputError, ConflictError, NotFoundError, PayloadTooLargeError
from driftmap.formats.drive_json import lens_to_json
from driftmap.formats.frame_images import encode_png
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.services.cameras import calibration as cal
from driftmap.services.cameras import profiles as profile_service
from driftmap.store.models import CameraProfile
from driftmap.store.storage import Storage
from tests.core.imaging.boards import BOARD, PINHOLE, board_poses, render_view
from tests.floor_frames import pinhole_camera

FOCAL_REL_TOL = 0.01
CAMERA: dict[str, Any] = {
    "width": 64,
    "height": 48,
    "ground_roi": [16, 24, 32, 20],
    "k_x": 0.02,
    "k_y": 0.03,
    "y_c": 0.5,
    "y_h": 4.0,
    "forward_sign": 1,
}
CLICKS_PX = np.array([[15.0, 100.0], [305.0, 100.0], [310.0, 235.0], [10.0, 235.0], [160.0, 170.0]])


@pytest.fixture(scope="module")
def views() -> list[tuple[str, NDArray[np.uint8]]]:
    """Five views of the board through ``PINHOLE`` (640x480) and a blank image between them."""
    seen = [
        (f"view{k}.png", render_view(PINHOLE, r, t, ss=2)) for k, (r, t) in enumerate(board_poses(5, 0.45))
    ]
    return [*seen[:2], ("blank.png", np.full((480, 640), 128, np.uint8)), *seen[2:]]


@pytest.fixture(scope="module")
def found(views: list[tuple[str, NDArray[np.uint8]]]) -> cal.Intrinsics:
    return cal.calibrate_intrinsics(views, BOARD, "pinhole")


class TestIntrinsics:
    def test_views_in_order_and_skipped_names(self, found: cal.Intrinsics) -> None:
        assert [name for name, _rms in found.views] == [f"view{k}.png" for k in range(5)]
        assert found.skipped == ("blank.png",)
        assert (found.width_px, found.height_px) == (640, 480)
        assert abs(found.lens.K[0][0] / PINHOLE.K[0][0] - 1) < FOCAL_REL_TOL

    def test_images_of_another_size_are_named(self, views: list[tuple[str, NDArray[np.uint8]]]) -> None:
        with pytest.raises(BadInputError, match="is 320x240, the first image 640x480") as err:
            cal.calibrate_intrinsics(
                [views[0], ("small.png", np.zeros((240, 320), np.uint8))], BOARD, "pinhole"
            )
        assert (err.value.file, err.value.field) == ("small.png", "images")

    def test_too_few_views_name_the_field_and_the_skipped(
        self, views: list[tuple[str, NDArray[np.uint8]]]
    ) -> None:
        with pytest.raises(BadInputError, match=r"found in 2 view\(s\).*blank.png") as err:
            cal.calibrate_intrinsics(views[:3], BOARD, "pinhole", field="video")
        assert err.value.field == "video"

    def test_unknown_model_and_no_images(self) -> None:
        with pytest.raises(BadInputError) as err:
            cal.calibrate_intrinsics([], BOARD, "orthographic")
        assert err.value.field == "model"
        with pytest.raises(BadInputError, match="no images") as err:
            cal.calibrate_intrinsics([], BOARD, "pinhole")
        assert err.value.field == "images"

    def test_decoding_names_a_file_that_is_not_an_image(self) -> None:
        good = encode_png(np.zeros((4, 4), np.uint8))
        decoded = cal.decode_images([("a.png", good), ("b.txt", b"text")])
        assert next(decoded)[0] == "a.png"
        with pytest.raises(BadInputError) as err:
            next(decoded)
        assert (err.value.file, err.value.field) == ("b.txt", "images")

    def test_decoding_checks_the_pixel_limit_first(self) -> None:
        big = encode_png(np.zeros((40, 50), np.uint8))
        with pytest.raises(PayloadTooLargeError) as err:
            next(cal.decode_images([("big.png", big)], max_pixels=1999))
        assert (err.value.file, err.value.field) == ("big.png", "images")
        with pytest.raises(PayloadTooLargeError):
            cal.calibrate_intrinsics(
                [("frame 0", np.zeros((40, 50), np.uint8))], BOARD, "pinhole", max_pixels=1999
            )

    @pytest.mark.parametrize(("text", "board"), [("8x6", Board(8, 6, 0.03)), (" 9 X 5 ", Board(9, 5, 0.03))])
    def test_board_text(self, text: str, board: Board) -> None:
        assert cal.parse_board(text, 0.03) == board

    def test_charuco_board(self) -> None:
        board = cal.parse_board("9x6", 0.03, marker_m=0.022)
        assert (board.is_charuco, board.dictionary, board.describe()) == (True, "DICT_4X4_50", "9x6 ChArUco")
        assert (
            cal.parse_board("9x6", 0.03, marker_m=0.022, dictionary="DICT_5X5_100").dictionary
            == "DICT_5X5_100"
        )
        with pytest.raises(BadInputError, match="needs the markers' side") as err:
            cal.parse_board("9x6", 0.03, dictionary="DICT_5X5_100")
        assert err.value.field == "marker_m"

    def test_a_board_on_the_floor_must_be_a_chessboard(self) -> None:
        board = cal.parse_board("9x6", 0.03, marker_m=0.022)
        with pytest.raises(BadInputError, match="plain chessboard") as err:
            cal.board_ground_points(np.zeros((48, 64), np.uint8), "floor.png", board, (2.0, 0.0), 0.0, None)
        assert err.value.field == "board"

    def test_bad_board_text_names_the_callers_field(self) -> None:
        with pytest.raises(BadInputError) as err:
            cal.parse_board("8by6", 0.03, field="--board")
        assert err.value.field == "--board"


class TestAddLens:
    def test_a_new_lens_drops_the_fitted_ground(self, found: cal.Intrinsics) -> None:
        block = {
            **CAMERA,
            "width": 640,
            "height": 480,
            "ground_homography": [[1, 0, 0], [0, 1, 0], [0, 0, 1]],
        }
        out, dropped = cal.add_lens(block, found)
        assert dropped == ["k_x", "k_y", "y_h", "ground_homography"]
        assert out["lens"] == lens_to_json(found.lens) and out["ground_roi"] == CAMERA["ground_roi"]
        again, none = cal.add_lens({**out, "k_x": 0.01}, found)
        assert none == [] and again["k_x"] == 0.01

    def test_another_frame_size_is_refused(self, found: cal.Intrinsics) -> None:
        with pytest.raises(BadInputError, match="says 64x48") as err:
            cal.add_lens(dict(CAMERA), found, "camera.json")
        assert (err.value.file, err.value.field) == ("camera.json", "camera.width")


class TestGround:
    def test_exact_points_and_the_block_values(self) -> None:
        truth = pinhole_camera()
        floor = apply_homography(np.asarray(truth.homography()), CLICKS_PX)
        ground = cal.fit_ground_points(CLICKS_PX, floor, 320, 240, truth.ground_roi_px)
        values = ground.block_values()
        assert values["ground_roi"] == list(truth.ground_roi_px)
        assert abs(values["k_x"] / truth.k_x_m_per_px - 1) < 1e-6
        assert abs(values["y_h"] / truth.y_h_m - 1) < 1e-6
        assert len(ground.fit.residuals_m) == len(CLICKS_PX)
        block = cal.add_ground({"width": 320, "height": 240}, ground, forward_sign=-1)
        assert (block["y_c"], block["forward_sign"]) == (0.0, -1)
        assert cal.add_ground({**block, "y_c": 1.5}, ground)["y_c"] == 1.5

    def test_the_default_roi_is_the_points_box(self) -> None:
        floor = apply_homography(np.asarray(pinhole_camera().homography()), CLICKS_PX)
        assert cal.fit_ground_points(CLICKS_PX, floor, 320, 240).roi == (10, 100, 301, 136)

    def test_refusals_name_their_field(self) -> None:
        floor = apply_homography(np.asarray(pinhole_camera().homography()), CLICKS_PX)
        with pytest.raises(BadInputError) as err:
            cal.fit_ground_points(CLICKS_PX, floor, 320, 240, (300, 200, 50, 50), roi_field="--roi")
        assert err.value.field == "--roi"
        with pytest.raises(BadInputError) as err:
            cal.fit_ground_points(np.zeros((0, 2)), np.zeros((0, 2)), 320, 240)
        assert err.value.field == "points"
        dup = CLICKS_PX.copy()
        dup[3] = dup[0]
        with pytest.raises(BadInputError, match="points 1 and 4 are the same") as err:
            cal.fit_ground_points(dup, floor, 320, 240, (10, 100, 200, 100))
        assert err.value.field == "points"

    def test_a_lens_field_is_named_without_the_camera_prefix(self) -> None:
        with pytest.raises(BadInputError) as err:
            cal.parse_lens({"model": "pinhole", "K": [[1, 0], [0, 1]], "distortion": [0, 0, 0, 0]})
        assert err.value.field is not None and err.value.field.startswith("lens")


class TestProfiles:
    def test_create_update_delete(self, storage: Storage) -> None:
        with storage.db.session() as session:
            profile = profile_service.create_profile(session, "  rear  ", CAMERA, "on every LHD")
            assert profile.name == "rear" and profile.camera == CAMERA
            with pytest.raises(ConflictError):
                profile_service.create_profile(session, "rear", CAMERA)
            profile_service.update_profile(session, profile, camera={**CAMERA, "y_c": 1.0})
            assert profile_service.get_profile(session, profile.id).camera["y_c"] == 1.0
            assert [p.name for p in profile_service.list_profiles(session)] == ["rear"]
            profile_service.delete_profile(session, profile)
            with pytest.raises(NotFoundError):
                profile_service.get_profile(session, profile.id)

    def test_a_bad_update_changes_nothing(self, storage: Storage) -> None:
        with storage.db.session() as session:
            profile = profile_service.create_profile(session, "rear", CAMERA)
            with pytest.raises(BadInputError) as err:
                profile_service.update_profile(
                    session, profile, name="new", camera={**CAMERA, "forward_sign": 2}
                )
            assert err.value.field == "camera.forward_sign"
            assert (profile.name, profile.camera) == ("rear", CAMERA)
            with pytest.raises(BadInputError) as err:
                profile_service.create_profile(session, "", CAMERA)
            assert err.value.field == "name"
            assert session.query(CameraProfile).count() == 1

    def test_assigning_copies_the_block(self, storage: Storage) -> None:
        with storage.db.session() as session:
            site = site_service.create_site(session, "mine")
            vehicle, _token = vehicle_service.create_vehicle(session, "lhd-1", site.id)
            profile = profile_service.create_profile(session, "rear", CAMERA)
            assert profile_service.assign_profile(session, vehicle, profile.id) == CAMERA
            profile_service.update_profile(session, profile, camera={**CAMERA, "k_x": 0.5})
            assert vehicle.camera == CAMERA  # a copy: the profile's later edits do not reach the vehicle
            for bad in (True, "1", 0):
                with pytest.raises(BadInputError) as err:
                    profile_service.assign_profile(session, vehicle, bad)
                assert err.value.field == "profile"
