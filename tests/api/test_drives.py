"""Drive routes on a real SQLite file (TestClient; import jobs run in huey's immediate mode)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import cv2
import httpx
import numpy as np
import pytest
from sqlalchemy import func, select

from driftmap.config import Settings
from driftmap.store.job_models import Job
from driftmap.store.models import Drive, Frame, Grounding
from driftmap.store.storage import Storage
from tests.api.data_helpers import ApiUsers, api_users, create_site_with_survey, upload_zip
from tests.jobs.mini_site import drive_folders, zip_folder


@pytest.fixture
def site_id(users: ApiUsers, mini_site: Path) -> int:
    """Unlike the shared ``site_id``: a site made through the API with the survey only, no drives yet."""
    return create_site_with_survey(users, mini_site)


def _stored(storage: Storage) -> tuple[int, int, int, int, int]:
    """(drives, frames, groundings, jobs, blobs)."""
    with storage.db.session() as session:
        counts = [
            session.scalar(select(func.count()).select_from(m)) or 0 for m in (Drive, Frame, Grounding, Job)
        ]
    return (*counts, len(storage.blobs.all_names()))  # type: ignore[return-value]


def _camera(mini_site: Path) -> dict[str, object]:
    camera: dict[str, object] = json.loads((drive_folders(mini_site, "map")[0] / "drive.json").read_text())[
        "camera"
    ]
    return camera


class TestZipUpload:
    def test_zip_is_imported_by_a_job_and_served_back(
        self, users: ApiUsers, site_id: int, mini_site: Path
    ) -> None:
        folder = drive_folders(mini_site, "map")[0]
        response = upload_zip(users, site_id, "map.zip", zip_folder(folder))
        assert response.status_code == 202, response.text
        assert response.headers["location"] == f"/api/jobs/{response.json()['id']}"  # where to follow it
        job = users.job(response.json()["id"])
        assert job["status"] == "succeeded", job["error"]
        assert users.get(response.headers["location"])["id"] == job["id"]
        drive_id = job["result"]["drive_id"]
        drive = users.get(f"/api/drives/{drive_id}")
        assert (drive["name"], drive["kind"], drive["frame_count"]) == (folder.name, "mapping", 100)
        assert drive["has_truth"] and drive["grounding_count"] == 1 and drive["duration_s"] > 0
        listed = users.get(f"/api/sites/{site_id}/drives")
        assert listed["total"] == 1 and listed["items"][0]["id"] == drive_id
        frames = users.get(f"/api/drives/{drive_id}/frames", params={"offset": 10, "limit": 5})
        assert frames["index"] == [10, 11, 12, 13, 14] and frames["total"] == 100
        image = users.client.get(f"/api/drives/{drive_id}/frames/7", headers=users.auth("viewer"))
        assert image.status_code == 200 and image.headers["content-type"] == "image/png"
        assert image.content == (folder / "frames" / "000007.png").read_bytes()
        thumb = users.client.get(
            f"/api/drives/{drive_id}/frames/7/thumbnail?width=80", headers=users.auth("viewer")
        )
        decoded = cv2.imdecode(np.frombuffer(thumb.content, np.uint8), cv2.IMREAD_UNCHANGED)
        assert thumb.headers["content-type"] == "image/png" and decoded.shape[1] == 80
        missing = users.client.get(f"/api/drives/{drive_id}/frames/100", headers=users.auth("viewer"))
        assert missing.status_code == 404

    def test_a_zip_recorded_with_a_camera_profile(
        self, users: ApiUsers, site_id: int, mini_site: Path
    ) -> None:
        """A profile's camera replaces drive.json's; one of another frame size is refused, nothing stored."""
        folder = drive_folders(mini_site, "loc")[0]
        camera = {**_camera(mini_site), "k_x": 0.0123}
        profiles = [
            users.client.post(
                "/api/camera-profiles", json={"name": name, "camera": cam}, headers=users.auth("surveyor")
            ).json()["id"]
            for name, cam in (("zip-cam", camera), ("big-cam", {**camera, "width": 640, "height": 480}))
        ]
        before = _stored(users.storage)
        refused = users.client.post(
            f"/api/sites/{site_id}/drives/zip",
            files={"file": ("loc.zip", zip_folder(folder), "application/zip")},
            data={"profile": str(profiles[1])},
            headers=users.auth("surveyor"),
        )
        assert refused.status_code == 422 and refused.json()["field"] == "camera", refused.text
        assert "640x480" in refused.json()["detail"] and _stored(users.storage) == before
        response = users.client.post(
            f"/api/sites/{site_id}/drives/zip",
            files={"file": ("loc.zip", zip_folder(folder), "application/zip")},
            data={"profile": str(profiles[0])},
            headers=users.auth("surveyor"),
        )
        assert response.status_code == 202, response.text
        job = users.job(response.json()["id"])
        assert job["status"] == "succeeded", job["error"]
        assert users.get(f"/api/drives/{job['result']['drive_id']}")["camera"]["k_x"] == 0.0123

    def test_zip_with_the_folder_at_its_root_works_too(
        self, users: ApiUsers, site_id: int, mini_site: Path
    ) -> None:
        response = upload_zip(
            users, site_id, "flat.zip", zip_folder(drive_folders(mini_site, "loc")[0], top=False)
        )
        assert users.job(response.json()["id"])["status"] == "succeeded"

    def test_not_a_zip_is_a_400_naming_the_file_and_stores_nothing(
        self, users: ApiUsers, site_id: int
    ) -> None:
        before = _stored(users.storage)
        response = upload_zip(users, site_id, "east.zip", b"PK\x03\x04 this is not really a zip")
        assert response.status_code == 400, response.text
        assert response.json()["file"] == "east.zip" and "zip" in response.json()["detail"]
        assert _stored(users.storage) == before

    def test_a_bad_frames_csv_names_the_file_line_and_field(
        self, users: ApiUsers, site_id: int, mini_site: Path, tmp_path: Path
    ) -> None:
        folder = tmp_path / "east"
        shutil.copytree(drive_folders(mini_site, "map")[0], folder)
        lines = (folder / "frames.csv").read_text().splitlines()
        lines[5] = lines[5].replace(lines[5].split(",")[1], "oops", 1)
        (folder / "frames.csv").write_text("\n".join(lines) + "\n")
        before = _stored(users.storage)
        response = upload_zip(users, site_id, "east.zip", zip_folder(folder))
        assert response.status_code == 422, response.text
        body = response.json()
        assert (body["file"], body["line"], body["field"]) == ("east.zip: east/frames.csv", 6, "t")
        assert _stored(users.storage) == before

    def test_a_truncated_frame_fails_the_job_and_stores_nothing(
        self, users: ApiUsers, site_id: int, mini_site: Path, tmp_path: Path
    ) -> None:
        folder = tmp_path / "east"
        shutil.copytree(drive_folders(mini_site, "map")[0], folder)
        frame = folder / "frames" / "000050.png"
        frame.write_bytes(frame.read_bytes()[:300])
        before = _stored(users.storage)
        response = upload_zip(users, site_id, "east.zip", zip_folder(folder))
        job = users.job(response.json()["id"])
        assert job["status"] == "failed" and "east.zip: east/frames/000050.png" in job["error"]
        drives, frames, groundings, jobs, blobs = _stored(users.storage)
        assert (drives, frames, groundings, jobs, blobs) == (*before[:3], before[3] + 1, before[4])

    def test_missing_drive_json_and_duplicate_names_are_refused(
        self, users: ApiUsers, site_id: int, mini_site: Path
    ) -> None:
        folder = drive_folders(mini_site, "map")[0]
        response = upload_zip(users, site_id, "nojson.zip", zip_folder(folder, skip=("drive.json",)))
        assert response.status_code == 422 and "drive.json" in response.json()["detail"]
        assert upload_zip(users, site_id, "a.zip", zip_folder(folder)).status_code == 202
        again = upload_zip(users, site_id, "b.zip", zip_folder(folder))
        assert again.status_code == 409 and folder.name in again.json()["detail"]

    def test_uploads_over_the_limit_are_refused(self, tmp_path: Path, mini_site: Path) -> None:
        small = api_users(Settings(data_dir=tmp_path / "small", max_upload_bytes=10_000))
        created = small.client.post("/api/sites", json={"name": "s"}, headers=small.auth("admin"))
        site_id = created.json()["id"]
        response = upload_zip(small, site_id, "big.zip", zip_folder(drive_folders(mini_site, "map")[0]))
        assert response.status_code == 413, response.text
        assert _stored(small.storage)[:4] == (0, 0, 0, 0)
        small.client.close()

    def test_viewers_cannot_upload(self, users: ApiUsers, site_id: int, mini_site: Path) -> None:
        response = upload_zip(
            users, site_id, "a.zip", zip_folder(drive_folders(mini_site, "map")[0]), role="viewer"
        )
        assert response.status_code == 403


class TestVideoUpload:
    def test_video_with_calibration_becomes_a_drive(
        self, users: ApiUsers, site_id: int, mini_site: Path, tmp_path: Path
    ) -> None:
        camera = _camera(mini_site)
        size = (int(str(camera["width"])), int(str(camera["height"])))
        video = tmp_path / "clip.avi"
        writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 5.0, size)
        rng = np.random.default_rng(3)
        for _ in range(6):
            writer.write(rng.integers(0, 256, (size[1], size[0], 3), dtype=np.uint8))
        writer.release()
        response = users.client.post(
            f"/api/sites/{site_id}/drives/video",
            files={
                "video": ("clip.avi", video.read_bytes(), "video/x-msvideo"),
                "calibration": ("camera.json", json.dumps({"camera": camera}).encode(), "application/json"),
            },
            data={"name": "clip", "kind": "localisation"},
            headers=users.auth("surveyor"),
        )
        assert response.status_code == 202, response.text
        assert response.headers["location"] == f"/api/jobs/{response.json()['id']}"
        job = users.job(response.json()["id"])
        assert job["status"] == "succeeded", job["error"]
        drive = users.get(f"/api/drives/{job['result']['drive_id']}")
        assert (drive["name"], drive["kind"], drive["frame_count"]) == ("clip", "localisation", 6)

    def test_a_bad_calibration_is_refused_before_anything_is_stored(
        self, users: ApiUsers, site_id: int, mini_site: Path
    ) -> None:
        camera = {**_camera(mini_site), "k_x": "fast"}
        before = _stored(users.storage)
        response = users.client.post(
            f"/api/sites/{site_id}/drives/video",
            files={
                "video": ("clip.avi", b"RIFF....AVI ", "video/x-msvideo"),
                "calibration": ("camera.json", json.dumps({"camera": camera}).encode(), "application/json"),
            },
            headers=users.auth("surveyor"),
        )
        assert response.status_code == 422 and response.json()["file"] == "camera.json"
        assert response.json()["field"] == "camera.k_x"
        assert _stored(users.storage) == before

    def test_a_video_recorded_with_a_camera_profile(
        self, users: ApiUsers, site_id: int, mini_site: Path, tmp_path: Path
    ) -> None:
        camera = _camera(mini_site)
        created = users.client.post(
            "/api/camera-profiles",
            json={"name": "rear-cam", "camera": camera},
            headers=users.auth("surveyor"),
        )
        assert created.status_code == 201, created.text
        size = (int(str(camera["width"])), int(str(camera["height"])))
        video = tmp_path / "clip.avi"
        writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"MJPG"), 5.0, size)
        for _ in range(4):
            writer.write(np.full((size[1], size[0], 3), 90, dtype=np.uint8))
        writer.release()
        clip = ("clip.avi", video.read_bytes(), "video/x-msvideo")
        response = users.client.post(
            f"/api/sites/{site_id}/drives/video",
            files={"video": clip},
            data={"profile": str(created.json()["id"]), "name": "profiled"},
            headers=users.auth("surveyor"),
        )
        assert response.status_code == 202, response.text
        job = users.job(response.json()["id"])
        assert job["status"] == "succeeded", job["error"]
        drive = users.get(f"/api/drives/{job['result']['drive_id']}")
        assert drive["camera"]["k_x"] == camera["k_x"] and drive["frame_count"] == 4

    def test_a_video_needs_a_calibration_or_a_profile_and_not_both(
        self, users: ApiUsers, site_id: int, mini_site: Path
    ) -> None:
        before = _stored(users.storage)
        clip = ("clip.avi", b"RIFF....AVI ", "video/x-msvideo")
        calibration = ("camera.json", json.dumps({"camera": _camera(mini_site)}).encode(), "application/json")
        for files, data in (
            ({"video": clip}, {}),
            ({"video": clip, "calibration": calibration}, {"profile": "1"}),
        ):
            response = users.client.post(
                f"/api/sites/{site_id}/drives/video", files=files, data=data, headers=users.auth("surveyor")
            )
            assert response.status_code == 422 and response.json()["field"] == "calibration", response.text
        response = users.client.post(
            f"/api/sites/{site_id}/drives/video",
            files={"video": clip},
            data={"profile": "999"},
            headers=users.auth("surveyor"),
        )
        assert response.status_code == 404
        assert _stored(users.storage) == before


class TestFrameByFrame:
    def test_frames_are_appended_in_order_and_checked(
        self, users: ApiUsers, site_id: int, mini_site: Path
    ) -> None:
        camera = _camera(mini_site)
        body = {"name": "live-rec", "kind": "localisation", "fps": 10.0, "camera": camera}
        created = users.client.post(f"/api/sites/{site_id}/drives", json=body, headers=users.auth("surveyor"))
        assert created.status_code == 201, created.text
        drive_id = created.json()["id"]
        frames = sorted((drive_folders(mini_site, "loc")[0] / "frames").iterdir())[:3]

        def post(data: bytes, t: float, content_type: str = "image/png") -> httpx.Response:
            return users.client.post(
                f"/api/drives/{drive_id}/frames",
                params={"t": t},
                content=data,
                headers={**users.auth("surveyor"), "Content-Type": content_type},
            )

        for k, file in enumerate(frames):
            response = post(file.read_bytes(), 0.1 * k)
            assert response.status_code == 201, response.text
            assert response.json()["index"] == k
        assert post(frames[0].read_bytes(), 0.1).status_code == 422
        assert post(frames[0].read_bytes(), 1.0, "text/plain").status_code == 400
        small = cv2.imencode(".png", np.zeros((10, 10), np.uint8))[1].tobytes()
        wrong_size = post(small, 1.0)
        assert wrong_size.status_code == 422 and "pixels" in wrong_size.json()["detail"]
        assert users.get(f"/api/drives/{drive_id}")["frame_count"] == 3


class TestDelete:
    def test_delete_removes_rows_and_unshared_blobs(
        self, users: ApiUsers, site_id: int, mini_site: Path
    ) -> None:
        before = _stored(users.storage)
        job = users.job(
            upload_zip(users, site_id, "m.zip", zip_folder(drive_folders(mini_site, "map")[0])).json()["id"]
        )
        drive_id = job["result"]["drive_id"]
        assert (
            users.client.delete(f"/api/drives/{drive_id}", headers=users.auth("surveyor")).status_code == 403
        )
        assert users.client.delete(f"/api/drives/{drive_id}", headers=users.auth("admin")).status_code == 204
        drives, frames, groundings, _jobs, blobs = _stored(users.storage)
        assert (drives, frames, groundings, blobs) == (before[0], before[1], before[2], before[4])
        assert users.client.get(f"/api/drives/{drive_id}", headers=users.auth("viewer")).status_code == 404
