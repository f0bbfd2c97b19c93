"""Vehicles and their tokens through the API, on a real SQLite file."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from driftmap.config import Settings
from driftmap.store.access_models import Vehicle
from driftmap.store.storage import Storage
from tests.api.access_helpers import Actors, make_actors


@pytest.fixture
def actors(settings: Settings) -> Iterator[Actors]:
    made = make_actors(settings)
    yield made
    made.client.close()


def _frames_url(vehicle_id: int) -> str:
    return f"/api/vehicles/{vehicle_id}/frames?t=1"


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
