"""Camera calibration, previews and camera profiles through the API, on a real database: chessboards rendered
through a known lens, floor points of a known homography, a floor patch of known size seen through a fisheye."""

from __future__ import annotations

import base64
import dataclasses
import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import pytest

from driftmap.config import Settings
from driftmap.core.imaging.lens import undistort_image, undistort_points
from driftmap.core.odometry.grid import apply_homography
from driftmap.formats.drive_folder import write_drive_folder
from driftmap.formats.drive_json import camera_to_json, lens_to_json
from driftmap.formats.frame_images import decode_gray, encode_png
from driftmap.formats.records import DriveMeta, FrameRow
from driftmap.services import drives as drive_service
from driftmap.services import sites as site_service
from driftmap.services.cameras import drive_check
from driftmap.store.access_models import Vehicle
from driftmap.store.models import CameraProfile
from driftmap.store.storage import Storage
from tests.api.access_helpers import Actors, make_actors
from tests.core.imaging.boards import CHARUCO, FISHEYE, PINHOLE, board_poses, render_view
from tests.core.odometry.test_turn_check import TRUE_Y_C_M, Y_C_TOL_M, mirrored, straight_then_turn
from tests.floor_frames import PATCH_M, patch_frame, pinhole_camera

FOCAL_REL_TOL = 0.01  # issue 21: focal length within 1 %
RMS_TOL_PX = 0.5  # reprojection RMS
SCALE_REL_TOL = 0.01  # issue 21: k_x, k_y within 1 % from 4 points measured to 1 cm
NOISE_M = 0.01
PATCH_TOL_M = 0.03  # the floor patch's sides in the bird's-eye view (view pixels of 1 cm, two resamplings)
VIEWS = 8
BOARD_FORM = {"board": "8x6", "square_m": "0.03", "model": "pinhole"}
WIDE_CLICKS_PX = [[15.0, 100.0], [305.0, 100.0], [310.0, 235.0], [10.0, 235.0]]  # 320x240 test camera
CAMERA = {
    "width": 64,
    "height": 48,
    "ground_roi": [16, 24, 32, 20],
    "k_x": 0.02,
    "k_y": 0.03,
    "y_c": 0.5,
    "y_h": 4.0,
    "forward_sign": 1,
}


@pytest.fixture
def actors(settings: Settings) -> Iterator[Actors]:
    made = make_actors(settings)
    yield made
    made.client.close()


@pytest.fixture(scope="module")
def board_pngs() -> list[tuple[str, bytes]]:
    """``VIEWS`` PNG views of the 8x6 board through ``PINHOLE`` (640x480), and a blank image."""
    views = [
        (f"view{k}.png", encode_png(render_view(PINHOLE, r, t, ss=2)))
        for k, (r, t) in enumerate(board_poses(VIEWS, 0.45))
    ]
    return [*views, ("blank.png", encode_png(np.full((480, 640), 128, np.uint8)))]


def _files(named: list[tuple[str, bytes]], kind: str = "image/png") -> list[tuple[str, Any]]:
    return [("images", (name, data, kind)) for name, data in named]


def _error(response: Any, status: int = 422) -> dict[str, Any]:
    assert response.status_code == status, response.text
    body: dict[str, Any] = response.json()
    return body


class TestIntrinsics:
    def test_recovers_the_lens_and_names_skipped_images(
        self, actors: Actors, board_pngs: list[tuple[str, bytes]]
    ) -> None:
        response = actors.client.post(
            "/api/cameras/intrinsics",
            data=BOARD_FORM,
            files=_files(board_pngs),
            headers=actors.auth("surveyor"),
        )
        assert response.status_code == 200, response.text
        body = response.json()
        k, truth = body["lens"]["K"], PINHOLE.K
        assert body["lens"]["model"] == "pinhole" and (body["width"], body["height"]) == (640, 480)
        assert abs(k[0][0] / truth[0][0] - 1) < FOCAL_REL_TOL
        assert abs(k[1][1] / truth[1][1] - 1) < FOCAL_REL_TOL
        assert body["rms_px"] <= RMS_TOL_PX
        assert [v["name"] for v in body["views"]] == [f"view{k}.png" for k in range(VIEWS)]
        assert max(v["rms_px"] for v in body["views"]) <= RMS_TOL_PX
        assert body["skipped"] == ["blank.png"]

    def test_a_charuco_board(self, actors: Actors) -> None:
        views = [
            (f"charuco{k}.png", encode_png(render_view(PINHOLE, r, t, CHARUCO, ss=2)))
            for k, (r, t) in enumerate(board_poses(4, 0.45, board=CHARUCO))
        ]
        form = {"board": "9x6", "square_m": "0.03", "marker_m": "0.022", "dictionary": "DICT_4X4_50"}
        response = actors.client.post(
            "/api/cameras/intrinsics", data=form, files=_files(views), headers=actors.auth("surveyor")
        )
        assert response.status_code == 200, response.text
        assert abs(response.json()["lens"]["K"][0][0] / PINHOLE.K[0][0] - 1) < FOCAL_REL_TOL
        bad = {**form, "dictionary": "DICT_9X9_1"}
        body = _error(
            actors.client.post(
                "/api/cameras/intrinsics", data=bad, files=_files(views), headers=actors.auth("surveyor")
            )
        )
        assert body["field"] == "dictionary" and "DICT_4X4_50" in body["detail"]

    def test_too_few_views_is_422_naming_images(
        self, actors: Actors, board_pngs: list[tuple[str, bytes]]
    ) -> None:
        files = _files([board_pngs[0], board_pngs[1], board_pngs[-1]])
        body = _error(
            actors.client.post(
                "/api/cameras/intrinsics", data=BOARD_FORM, files=files, headers=actors.auth("surveyor")
            )
        )
        assert body["field"] == "images"
        assert "found in 2 view(s)" in body["detail"] and "blank.png" in body["detail"]

    def test_a_file_that_is_not_an_image_is_422_naming_it(
        self, actors: Actors, board_pngs: list[tuple[str, bytes]]
    ) -> None:
        files = _files([board_pngs[0], ("notes.txt", b"not an image at all")])
        body = _error(
            actors.client.post(
                "/api/cameras/intrinsics", data=BOARD_FORM, files=files, headers=actors.auth("surveyor")
            )
        )
        assert (body["field"], body["file"]) == ("images", "notes.txt")

    def test_a_video_of_the_board(
        self, actors: Actors, board_pngs: list[tuple[str, bytes]], tmp_path: Path
    ) -> None:
        path = tmp_path / "board.avi"
        writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"MJPG"), 5.0, (640, 480), isColor=False)
        for _name, data in board_pngs[:4]:
            writer.write(cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_GRAYSCALE))
        writer.release()
        response = actors.client.post(
            "/api/cameras/intrinsics",
            data={**BOARD_FORM, "every": "1"},
            files={"video": ("board.avi", path.read_bytes(), "video/x-msvideo")},
            headers=actors.auth("surveyor"),
        )
        assert response.status_code == 200, response.text
        assert [v["name"] for v in response.json()["views"]] == [f"board.avi#frame {k}" for k in range(4)]

    def test_an_unreadable_video_is_422_naming_video(self, actors: Actors) -> None:
        files = {"video": ("board.mp4", b"no video here", "video/mp4")}
        body = _error(
            actors.client.post(
                "/api/cameras/intrinsics", data=BOARD_FORM, files=files, headers=actors.auth("surveyor")
            )
        )
        assert (body["field"], body["file"]) == ("video", "board.mp4")

    def test_bad_board_and_no_images(self, actors: Actors, board_pngs: list[tuple[str, bytes]]) -> None:
        surveyor = actors.auth("surveyor")
        form = {**BOARD_FORM, "board": "8by6"}
        bad = actors.client.post(
            "/api/cameras/intrinsics", data=form, files=_files(board_pngs[:1]), headers=surveyor
        )
        assert _error(bad)["field"] == "board"
        none = actors.client.post("/api/cameras/intrinsics", data=BOARD_FORM, headers=surveyor)
        assert _error(none)["field"] == "images"

    def test_an_image_over_the_pixel_limit_is_413_before_decoding(
        self, settings: Settings, board_pngs: list[tuple[str, bytes]]
    ) -> None:
        small = make_actors(settings.model_copy(update={"max_frame_pixels": 320 * 240}))
        with small.client:
            response = small.client.post(
                "/api/cameras/intrinsics",
                data=BOARD_FORM,
                files=_files(board_pngs[:3]),
                headers=small.auth("surveyor"),
            )
        body = _error(response, 413)
        assert (body["field"], body["file"]) == ("images", "view0.png") and "640x480" in body["detail"]

    def test_viewers_cannot_calibrate(self, actors: Actors, board_pngs: list[tuple[str, bytes]]) -> None:
        response = actors.client.post(
            "/api/cameras/intrinsics",
            data=BOARD_FORM,
            files=_files(board_pngs[:1]),
            headers=actors.auth("viewer"),
        )
        assert response.status_code == 403


def _ground_body(clicks: list[list[float]], floor: np.ndarray) -> dict[str, Any]:
    points = [
        {"px": u, "py": v, "x_m": float(x), "y_m": float(y)}
        for (u, v), (x, y) in zip(clicks, floor, strict=True)
    ]
    camera = pinhole_camera()
    return {"points": points, "width": 320, "height": 240, "ground_roi": list(camera.ground_roi_px)}


class TestGround:
    def test_four_noisy_points_give_the_scales(self, actors: Actors) -> None:
        truth = pinhole_camera()
        floor = apply_homography(np.asarray(truth.homography()), np.asarray(WIDE_CLICKS_PX))
        floor += np.random.default_rng(21).normal(0.0, NOISE_M, floor.shape)
        response = actors.client.post(
            "/api/cameras/ground", json=_ground_body(WIDE_CLICKS_PX, floor), headers=actors.auth("surveyor")
        )
        assert response.status_code == 200, response.text
        body = response.json()
        assert abs(body["k_x"] / truth.k_x_m_per_px - 1) < SCALE_REL_TOL
        assert abs(body["k_y"] / truth.k_y_m_per_px - 1) < SCALE_REL_TOL
        assert body["ground_roi"] == list(truth.ground_roi_px) and len(body["residuals_m"]) == 4
        assert np.asarray(body["ground_homography"]).shape == (3, 3)

    def test_the_values_make_a_camera_block_a_vehicle_takes(self, actors: Actors) -> None:
        truth = pinhole_camera()
        clicks = [*WIDE_CLICKS_PX, [160.0, 170.0]]
        floor = apply_homography(np.asarray(truth.homography()), np.asarray(clicks))
        fitted = actors.client.post(
            "/api/cameras/ground", json=_ground_body(clicks, floor), headers=actors.auth("surveyor")
        ).json()
        assert max(fitted.pop("residuals_m")) < 1e-6
        block = {**fitted, "width": 320, "height": 240, "y_c": 1.5, "forward_sign": 1}
        put = actors.client.put(
            f"/api/vehicles/{actors.vehicle_id}/camera", json=block, headers=actors.auth("surveyor")
        )
        assert put.status_code == 200, put.text

    def test_collinear_points_are_refused_by_number(self, actors: Actors) -> None:
        clicks = [[10.0, 200.0], [100.0, 200.0], [200.0, 200.0], [50.0, 230.0]]
        floor = np.array([[3.0, 1.0], [3.0, 0.0], [3.0, -1.0], [2.0, 0.5]])
        body = _error(
            actors.client.post(
                "/api/cameras/ground", json=_ground_body(clicks, floor), headers=actors.auth("surveyor")
            )
        )
        assert body["field"] == "points" and "points 1, 2, 3 are collinear" in body["detail"]

    def test_a_bad_lens_and_an_roi_outside_the_frame(self, actors: Actors) -> None:
        floor = apply_homography(np.asarray(pinhole_camera().homography()), np.asarray(WIDE_CLICKS_PX))
        request = _ground_body(WIDE_CLICKS_PX, floor)
        lens = {
            "model": "pinhole",
            "K": [[-1.0, 0, 160], [0, 250, 120], [0, 0, 1]],
            "distortion": [0, 0, 0, 0],
        }
        surveyor = actors.auth("surveyor")
        bad_lens = actors.client.post("/api/cameras/ground", json={**request, "lens": lens}, headers=surveyor)
        assert _error(bad_lens)["field"].startswith("lens.")
        roi = {**request, "ground_roi": [300, 200, 100, 100]}
        assert (
            _error(actors.client.post("/api/cameras/ground", json=roi, headers=surveyor))["field"]
            == "ground_roi"
        )


def fisheye_floor() -> tuple[dict[str, Any], bytes]:
    """A 640x480 camera block with the ``FISHEYE`` lens, 1.5 m above the floor pitched 40 degrees down, and the
    PNG of a frame it records of the floor patch ``PATCH_M`` (the ideal view, distorted through the lens)."""
    width, height = 640, 480
    phi, height_m = math.radians(40.0), 1.5
    camera_from_floor = np.array(
        [
            [0, -1, 0],
            [-math.sin(phi), 0, height_m * math.cos(phi)],
            [math.cos(phi), 0, height_m * math.sin(phi)],
        ]
    )
    hom = np.linalg.inv(FISHEYE.matrix() @ camera_from_floor)  # undistorted pixel -> floor, look frame
    hom *= np.sign(hom[2] @ [width / 2, height - 1, 1]) / np.abs(hom).max()
    ideal = patch_frame(hom, (width, height))
    uu, vv = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    pix = undistort_points(FISHEYE, np.stack([uu.ravel(), vv.ravel()], axis=1)).reshape(height, width, 2)
    pix = np.where(np.isfinite(pix), pix, -10.0).astype(np.float32)
    raw = cv2.remap(ideal, pix[..., 0], pix[..., 1], cv2.INTER_LINEAR)
    block = {
        "width": width,
        "height": height,
        "lens": lens_to_json(FISHEYE),
        "ground_roi": [160, 180, 320, 220],
        "ground_homography": hom.tolist(),
    }
    return block, encode_png(np.asarray(raw, dtype=np.uint8))


def _preview(actors: Actors, block: dict[str, Any] | str, frame: bytes, role: str = "surveyor") -> Any:
    camera = block if isinstance(block, str) else json.dumps(block)
    return actors.client.post(
        "/api/cameras/preview",
        data={"camera": camera},
        files={"frame": ("floor.png", frame, "image/png")},
        headers=actors.auth(role),
    )


class TestPreview:
    def test_the_undistorted_image_and_the_floor_from_above(self, actors: Actors) -> None:
        block, frame = fisheye_floor()
        response = _preview(actors, block, frame)
        assert response.status_code == 200, response.text
        body = response.json()
        undistorted = decode_gray(base64.b64decode(body["undistorted_png"]))
        assert np.array_equal(
            undistorted, undistort_image(FISHEYE, decode_gray(frame))
        )  # K kept, not narrowed
        view = body["birdseye"]
        image = decode_gray(base64.b64decode(view["png"]))
        assert image.shape == (view["height"], view["width"]) and max(image.shape) <= 400
        rows, cols = np.nonzero(image > 145)  # the patch, half-way between floor and patch
        floor_from_px = np.asarray(view["floor_from_px"])
        far_left = floor_from_px @ [cols.min() - 0.5, rows.min() - 0.5, 1.0]
        near_right = floor_from_px @ [cols.max() + 0.5, rows.max() + 0.5, 1.0]
        (x0, x1), (y0, y1) = PATCH_M
        assert np.allclose([far_left[:2], near_right[:2]], [[x1, y1], [x0, y0]], atol=PATCH_TOL_M)
        assert len(view["footprint_px"]) == 4 and view["x_range_m"][0] < x0 < x1 < view["x_range_m"][1]

    def test_without_a_lens_or_a_homography(self, actors: Actors) -> None:
        frame = np.arange(64 * 48, dtype=np.uint8).reshape(48, 64)
        response = _preview(
            actors, {"width": 64, "height": 48, "ground_roi": [0, 0, 8, 8]}, encode_png(frame)
        )
        assert response.status_code == 200, response.text
        body = response.json()
        assert np.array_equal(decode_gray(base64.b64decode(body["undistorted_png"])), frame)
        assert body["birdseye"] is None

    def test_bad_input_is_422_naming_the_field(self, actors: Actors) -> None:
        block, frame = fisheye_floor()
        small = encode_png(np.zeros((240, 320), np.uint8))
        above = {**block, "ground_roi": [160, 20, 320, 200]}  # the horizon is the row v = 82
        cases: list[tuple[dict[str, Any] | str, bytes, str, str]] = [
            (block, b"not an image at all", "frame", "not a PNG or JPEG"),
            (block, small, "frame", "320x240"),
            (above, frame, "camera.ground_roi", "horizon"),
            (
                {**block, "ground_homography": [[1, 0, 0], [1, 0, 0], [0, 0, 1]]},
                frame,
                "camera.ground_homography",
                "singular",
            ),
            ({**block, "lens": {**block["lens"], "K": [[1, 0], [0, 1]]}}, frame, "camera.lens.K", "3x3"),
            ({k: v for k, v in block.items() if k != "ground_roi"}, frame, "camera.ground_roi", "needed"),
            ({**block, "width": "640"}, frame, "camera.width", "integer"),
            ("{not json", frame, "camera", "invalid JSON"),
        ]
        for camera, data, field, words in cases:
            body = _error(_preview(actors, camera, data))
            assert body["field"] == field and words in body["detail"], (field, body)

    def test_viewers_cannot_ask(self, actors: Actors) -> None:
        frame = encode_png(np.zeros((48, 64), np.uint8))
        assert _preview(actors, {"width": 64, "height": 48}, frame, role="viewer").status_code == 403


class TestProfiles:
    def test_crud_with_roles(self, actors: Actors) -> None:
        surveyor, viewer = actors.auth("surveyor"), actors.auth("viewer")
        new = {"name": "lhd rear", "description": "944x800 fisheye", "camera": CAMERA}
        assert actors.client.post("/api/camera-profiles", json=new, headers=viewer).status_code == 403
        created = actors.client.post("/api/camera-profiles", json=new, headers=surveyor)
        assert created.status_code == 201, created.text
        profile = created.json()
        assert profile["camera"] == {**CAMERA, "ground_homography": None, "lens": None}
        url = f"/api/camera-profiles/{profile['id']}"
        listed = actors.client.get("/api/camera-profiles", headers=viewer).json()
        assert listed["total"] == 1 and listed["items"][0]["name"] == "lhd rear"
        assert actors.client.get(url, headers=viewer).json()["description"] == "944x800 fisheye"
        assert actors.client.put(url, json={"name": "x"}, headers=viewer).status_code == 403
        assert actors.client.delete(url, headers=viewer).status_code == 403
        changed = actors.client.put(
            url, json={"name": "lhd rear v2", "camera": {**CAMERA, "k_x": 0.025}}, headers=surveyor
        )
        assert changed.status_code == 200, changed.text
        assert (changed.json()["name"], changed.json()["camera"]["k_x"]) == ("lhd rear v2", 0.025)
        assert (
            actors.client.post(
                "/api/camera-profiles", json={**new, "name": "lhd rear v2"}, headers=surveyor
            ).status_code
            == 409
        )
        assert actors.client.delete(url, headers=surveyor).status_code == 204
        assert actors.client.get(url, headers=viewer).status_code == 404

    def test_a_bad_block_stores_nothing(self, actors: Actors) -> None:
        surveyor = actors.auth("surveyor")
        bad = {"name": "broken", "camera": {**CAMERA, "ground_roi": [60, 40, 32, 20]}}
        assert (
            _error(actors.client.post("/api/camera-profiles", json=bad, headers=surveyor))["field"]
            == "camera.ground_roi"
        )
        missing = {"name": "broken", "camera": {k: v for k, v in CAMERA.items() if k != "k_y"}}
        assert (
            _error(actors.client.post("/api/camera-profiles", json=missing, headers=surveyor))["field"]
            == "camera.k_y"
        )
        created = actors.client.post(
            "/api/camera-profiles", json={"name": "ok", "camera": CAMERA}, headers=surveyor
        )
        url = f"/api/camera-profiles/{created.json()['id']}"
        bad_update = actors.client.put(
            url, json={"name": "renamed", "camera": {**CAMERA, "k_x": "fast"}}, headers=surveyor
        )
        assert _error(bad_update)["field"] == "camera.k_x"
        storage: Storage = actors.app.state.storage
        with storage.db.session() as session:
            stored = session.query(CameraProfile).all()
            assert [(p.name, p.camera["k_x"]) for p in stored] == [("ok", CAMERA["k_x"])]


class TestVehicleProfile:
    def test_assigning_a_profile_stores_its_block(self, actors: Actors) -> None:
        surveyor = actors.auth("surveyor")
        profile = actors.client.post(
            "/api/camera-profiles", json={"name": "rear", "camera": CAMERA}, headers=surveyor
        ).json()
        url = f"/api/vehicles/{actors.vehicle_id}/camera"
        assigned = actors.client.put(url, json={"profile": profile["id"]}, headers=surveyor)
        assert assigned.status_code == 200, assigned.text
        assert assigned.json() == profile["camera"]
        storage: Storage = actors.app.state.storage
        with storage.db.session() as session:
            vehicle = session.get(Vehicle, actors.vehicle_id)
            assert vehicle is not None and vehicle.camera == CAMERA
        assert actors.client.get(url, headers=actors.auth("viewer")).json()["k_x"] == CAMERA["k_x"]

    def test_unknown_or_bad_profile_changes_nothing(self, actors: Actors) -> None:
        surveyor = actors.auth("surveyor")
        url = f"/api/vehicles/{actors.vehicle_id}/camera"
        assert actors.client.put(url, json={"profile": 424242}, headers=surveyor).status_code == 404
        assert (
            _error(actors.client.put(url, json={"profile": "rear"}, headers=surveyor))["field"] == "profile"
        )
        assert actors.client.get(url, headers=surveyor).status_code == 404  # still no camera
        assert (
            actors.client.put(url, json=CAMERA, headers=surveyor).status_code == 200
        )  # the block form works


class TestCameraCheck:
    """``POST /api/drives/{id}/camera-check`` on a stored drive: straight, then 46 degrees left about a point
    0.5 m behind the camera whose block says 1.5 m and that it looks behind."""

    @pytest.fixture
    def drive_id(self, actors: Actors, storage: Storage, tmp_path: Path) -> int:
        frames = straight_then_turn()
        camera = dataclasses.replace(pinhole_camera(), forward_sign=-1)
        folder = tmp_path / "turn"
        rows = [FrameRow(i, i / 10) for i in range(len(frames))]
        write_drive_folder(folder, DriveMeta("turn", "mapping", 10.0, camera), rows, map(encode_png, frames))
        with storage.blobs.batch() as batch, storage.db.session() as session:
            site = site_service.create_site(session, "check")
            drive = drive_service.import_drive(session, batch, site, folder)
            session.commit()
            return drive.id

    def _check(self, actors: Actors, drive_id: int, body: dict[str, Any], role: str = "surveyor") -> Any:
        return actors.client.post(
            f"/api/drives/{drive_id}/camera-check", json=body, headers=actors.auth(role)
        )

    def test_the_mounting_from_a_turn(self, actors: Actors, drive_id: int) -> None:
        response = self._check(actors, drive_id, {"turn_deg": 45})
        assert response.status_code == 200, response.text
        body = response.json()
        assert body["sign_wrong"] and body["direction_wrong"] is False and body["ratio"] is None
        assert body["turned_deg"] == pytest.approx(46.4, abs=3.0) and body["y_c_m"] == 1.5
        assert body["fitted_y_c_m"] == pytest.approx(TRUE_Y_C_M, abs=Y_C_TOL_M)
        assert body["camera"]["forward_sign"] == 1 and body["camera"]["y_c"] == body["fitted_y_c_m"]
        assert body["turn_y_c_m"] == pytest.approx(TRUE_Y_C_M, abs=0.3)

    def test_a_mirrored_camera_is_not_corrected(self, actors: Actors, drive_id: int) -> None:
        block = camera_to_json(mirrored(dataclasses.replace(pinhole_camera(), forward_sign=-1)))
        body = self._check(actors, drive_id, {"turn_deg": 45, "camera": block}).json()
        assert body["direction_wrong"] is True and body["camera"] is None

    def test_the_scale_on_its_straight_part_is_asked_for_by_distance(
        self, actors: Actors, drive_id: int
    ) -> None:
        body = self._check(actors, drive_id, {"distance_m": 6.0}).json()
        assert body["ratio"] is not None and body["turned_deg"] is None and body["sign_wrong"]

    @pytest.mark.parametrize(
        ("body", "field"),
        [
            ({}, "distance_m"),
            ({"turn_deg": 45, "distance_m": 6}, "distance_m"),
            ({"turn_deg": 5}, "turn_deg"),
            ({"turn_deg": 45, "camera": {**CAMERA}}, "camera.width"),
            ({"turn_deg": 45, "camera": {"width": 320}}, "camera.height"),
        ],
    )
    def test_bad_requests_name_the_field(
        self, actors: Actors, drive_id: int, body: dict[str, Any], field: str
    ) -> None:
        assert _error(self._check(actors, drive_id, body))["field"] == field

    def test_a_drive_too_long_to_check_while_the_request_waits(
        self, actors: Actors, drive_id: int, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        monkeypatch.setattr(drive_check, "MAX_CHECK_FRAMES", 20)
        body = _error(self._check(actors, drive_id, {"turn_deg": 45}))
        assert body["field"] == "drive" and "25 frames" in body["detail"] and "at most 20" in body["detail"]

    def test_viewers_may_not_and_a_missing_drive_is_404(self, actors: Actors, drive_id: int) -> None:
        assert self._check(actors, drive_id, {"turn_deg": 45}, role="viewer").status_code == 403
        assert self._check(actors, drive_id + 1000, {"turn_deg": 45}).status_code == 404
