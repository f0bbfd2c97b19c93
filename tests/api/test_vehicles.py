"""Vehicles and their tokens through the API, on a real SQLite file."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from driftmap.config import Settings
from driftmap.store.access_models import Vehicle, VehicleLiveState
from driftmap.store.storage import Storage
from tests.api.access_helpers import Actors, make_actors


@pytest.fixture
def actors(settings: Settings) -> Iterator[Actors]:
    made = make_actors(settings)
    yield made
    made.client.close()


def _frames_url(vehicle_id: int) -> str:
    return f"/api/vehicles/{vehicle_id}/frames?t=1"


CAMERA = {
    "width": 64,
    "height": 48,
    "ground_roi": [16, 24, 32, 20],
    "k_x": 0.02,
    "k_y": 0.03,
    "y_c": 0.0,
    "y_h": 4.0,
    "forward_sign": 1,
}


class TestRegister:
    def test_admin_registers_a_vehicle_and_sees_its_token_once(self, actors: Actors) -> None:
        admin = actors.auth("admin")
        site_id = actors.client.get(f"/api/vehicles/{actors.vehicle_id}", headers=admin).json()["site_id"]
        created = actors.client.post(
            "/api/vehicles", json={"name": "truck-7", "site_id": site_id}, headers=admin
        )
        assert created.status_code == 201
        body = created.json()
        assert body["name"] == "truck-7" and body["token"].startswith(f"dmv_{body['id']}_")
        detail = actors.client.get(f"/api/vehicles/{body['id']}", headers=actors.auth("viewer")).json()
        assert "token" not in detail
        listed = actors.client.get("/api/vehicles", params={"site_id": site_id}, headers=admin).json()
        assert [v["name"] for v in listed] == ["lhd-1", "lhd-2", "truck-7"]
        storage: Storage = actors.app.state.storage
        with storage.db.session() as session:
            stored = session.get(Vehicle, body["id"])
            assert stored is not None and body["token"] not in stored.token_sha256

    def test_unknown_site_is_404_and_duplicate_name_409(self, actors: Actors) -> None:
        admin = actors.auth("admin")
        missing = actors.client.post("/api/vehicles", json={"name": "x", "site_id": 424242}, headers=admin)
        assert missing.status_code == 404 and "424242" in missing.json()["detail"]
        site_id = actors.client.get(f"/api/vehicles/{actors.vehicle_id}", headers=admin).json()["site_id"]
        dup = actors.client.post("/api/vehicles", json={"name": "lhd-1", "site_id": site_id}, headers=admin)
        assert dup.status_code == 409

    def test_missing_fields_are_422(self, actors: Actors) -> None:
        response = actors.client.post("/api/vehicles", json={"name": "x"}, headers=actors.auth("admin"))
        assert response.status_code == 422


class TestTokens:
    def test_rotating_the_token_retires_the_old_one(self, actors: Actors) -> None:
        old = actors.auth("vehicle")
        assert actors.client.post(_frames_url(actors.vehicle_id), headers=old).status_code == 400  # no body
        rotated = actors.client.post(f"/api/vehicles/{actors.vehicle_id}/token", headers=actors.auth("admin"))
        new_token = rotated.json()["token"]
        assert new_token != actors.tokens["vehicle"]
        assert actors.client.post(_frames_url(actors.vehicle_id), headers=old).status_code == 401
        new = {"Authorization": f"Bearer {new_token}"}
        assert actors.client.post(_frames_url(actors.vehicle_id), headers=new).status_code == 400

    def test_a_vehicle_posts_only_for_itself_and_reads_nothing(self, actors: Actors) -> None:
        mine = actors.auth("vehicle")
        assert actors.client.post(_frames_url(actors.other_vehicle_id), headers=mine).status_code == 403
        for path in ("/api/vehicles", f"/api/vehicles/{actors.vehicle_id}", "/api/positions/latest"):
            assert actors.client.get(path, headers=mine).status_code == 403

    def test_deleting_a_vehicle_removes_its_token(self, actors: Actors) -> None:
        admin = actors.auth("admin")
        assert actors.client.delete(f"/api/vehicles/{actors.vehicle_id}", headers=admin).status_code == 204
        assert actors.client.get(f"/api/vehicles/{actors.vehicle_id}", headers=admin).status_code == 404
        response = actors.client.post(_frames_url(actors.vehicle_id), headers=actors.auth("vehicle"))
        assert response.status_code == 401


class TestCamera:
    def _url(self, actors: Actors) -> str:
        return f"/api/vehicles/{actors.vehicle_id}/camera"

    def test_a_surveyor_sets_reads_and_deletes_the_camera(self, actors: Actors) -> None:
        url, surveyor, viewer = self._url(actors), actors.auth("surveyor"), actors.auth("viewer")
        detail = f"/api/vehicles/{actors.vehicle_id}"
        assert actors.client.get(url, headers=viewer).status_code == 404
        assert actors.client.get(detail, headers=viewer).json()["has_camera"] is False
        put = actors.client.put(url, json={**CAMERA, "note": "ignored"}, headers=surveyor)
        assert put.status_code == 200, put.text
        assert put.json() == {**CAMERA, "ground_homography": None, "lens": None}
        assert actors.client.get(url, headers=viewer).json() == put.json()
        assert actors.client.get(detail, headers=viewer).json()["has_camera"] is True
        listed = actors.client.get("/api/vehicles", headers=viewer).json()
        assert [v["has_camera"] for v in listed] == [True, False]
        homography = [[0.0, -0.1, 2.0], [-0.1, 0.0, 3.0], [0.0, 0.0, 1.0]]
        admin_put = actors.client.put(
            url, json={**CAMERA, "k_x": 0.5, "ground_homography": homography}, headers=actors.auth("admin")
        )
        assert admin_put.status_code == 200 and admin_put.json()["ground_homography"] == homography
        lens = {"model": "fisheye", "K": [[60.0, 0.0, 32.0], [0.0, 60.0, 24.0], [0.0, 0.0, 1.0]]}
        lens["distortion"] = [0.01, -0.002, 0.0, 0.0]
        with_lens = actors.client.put(url, json={**CAMERA, "lens": lens}, headers=surveyor)
        assert with_lens.status_code == 200, with_lens.text
        assert with_lens.json()["lens"] == lens == actors.client.get(url, headers=viewer).json()["lens"]
        assert actors.client.delete(url, headers=surveyor).status_code == 204
        assert actors.client.get(url, headers=viewer).status_code == 404
        assert actors.client.delete(url, headers=surveyor).status_code == 404
        assert actors.client.get(detail, headers=viewer).json()["has_camera"] is False

    @pytest.mark.parametrize(
        ("change", "field"),
        [
            ({"k_x": -1.0}, "camera.k_x"),
            ({"k_y": "fast"}, "camera.k_y"),
            ({"ground_roi": [40, 24, 32, 20]}, "camera.ground_roi"),
            ({"forward_sign": 0}, "camera.forward_sign"),
            ({"width": None}, "camera.width"),
            ({"ground_homography": [[1, 0], [0, 1]]}, "camera.ground_homography"),
        ],
    )
    def test_a_bad_block_is_refused_naming_the_field_and_the_old_camera_stays(
        self,
        actors: Actors,
        change: dict,
        field: str,  # type: ignore[type-arg]
    ) -> None:
        url, surveyor = self._url(actors), actors.auth("surveyor")
        assert actors.client.put(url, json=CAMERA, headers=surveyor).status_code == 200
        bad = actors.client.put(url, json={**CAMERA, **change}, headers=surveyor)
        assert bad.status_code == 422 and bad.json()["field"] == field, bad.text
        assert field in bad.json()["detail"]
        assert actors.client.get(url, headers=surveyor).json() == {
            **CAMERA,
            "ground_homography": None,
            "lens": None,
        }

    def test_a_missing_key_or_a_non_object_is_named(self, actors: Actors) -> None:
        url, surveyor = self._url(actors), actors.auth("surveyor")
        missing = actors.client.put(
            url, json={k: v for k, v in CAMERA.items() if k != "y_h"}, headers=surveyor
        )
        assert missing.status_code == 422 and missing.json()["field"] == "camera.y_h"
        listed = actors.client.put(url, json=[1, 2], headers=surveyor)
        assert listed.status_code == 422 and listed.json()["field"] == "camera"
        assert actors.client.get(url, headers=surveyor).status_code == 404

    def test_viewers_and_vehicles_cannot_change_it(self, actors: Actors) -> None:
        url = self._url(actors)
        for caller in ("viewer", "vehicle"):
            assert actors.client.put(url, json=CAMERA, headers=actors.auth(caller)).status_code == 403
            assert actors.client.delete(url, headers=actors.auth(caller)).status_code == 403
        assert actors.client.put(url, json=CAMERA).status_code == 401
        assert actors.client.get(url, headers=actors.auth("viewer")).status_code == 404

    def test_an_unknown_vehicle_is_404(self, actors: Actors) -> None:
        response = actors.client.put("/api/vehicles/424242/camera", json=CAMERA, headers=actors.auth("admin"))
        assert response.status_code == 404

    def test_a_new_camera_drops_the_live_state_and_keeps_the_counts(self, actors: Actors) -> None:
        storage: Storage = actors.app.state.storage
        with storage.db.session() as session:
            session.add(
                VehicleLiveState(
                    vehicle_id=actors.vehicle_id,
                    state_npz=b"belief",
                    last_t_s=7.0,
                    processed=5,
                    skipped=1,
                    out_of_order=2,
                )
            )
        with storage.db.session() as session:
            before = session.get(VehicleLiveState, actors.vehicle_id)
            assert before is not None
            revision = before.revision
        url, surveyor = self._url(actors), actors.auth("surveyor")
        assert actors.client.put(url, json=CAMERA, headers=surveyor).status_code == 200
        with storage.db.session() as session:
            state = session.get(VehicleLiveState, actors.vehicle_id)
            assert state is not None and state.state_npz is None and state.revision > revision
            assert (state.processed, state.skipped, state.out_of_order, state.last_t_s) == (5, 1, 2, 7.0)
            revision = state.revision
        assert actors.client.put(url, json=CAMERA, headers=surveyor).status_code == 200  # the same camera
        assert actors.client.delete(url, headers=surveyor).status_code == 204
        with storage.db.session() as session:
            state = session.get(VehicleLiveState, actors.vehicle_id)
            assert state is not None and state.revision == revision + 1
