"""Map-version routes on a real SQLite file: builds through the job (huey's immediate mode), read-back,
comparison of two versions, deletion."""

from __future__ import annotations

from typing import Any

from sqlalchemy import select

from driftmap.formats.csv_exports import LOCALISATION_HEADER
from driftmap.store.job_models import Job
from driftmap.store.models import MapPiece, MapVersion
from tests.api.data_helpers import ApiUsers


def build(users: ApiUsers, site_id: int, full: bool = False) -> dict[str, Any]:
    """Start a FAST build (``full``: no odometry reused); returns the finished job (immediate mode)."""
    response = users.client.post(
        f"/api/sites/{site_id}/maps", json={"preset": "fast", "full": full}, headers=users.auth("surveyor")
    )
    assert response.status_code == 202, response.text
    job = users.job(response.json()["id"])
    assert job["status"] == "succeeded", job["error"]
    return job


class TestBuildAndRead:
    def test_a_version_serves_poses_closures_nodes_and_residuals(self, users: ApiUsers, site_id: int) -> None:
        job = build(users, site_id)
        versions = users.get(f"/api/sites/{site_id}/maps")
        assert versions["total"] == 1 and versions["items"][0]["version"] == 1
        assert versions["items"][0]["created_by"] == f"surveyor via job {job['id']}"
        detail = users.get(f"/api/sites/{site_id}/maps/1")
        assert (detail["poses"], detail["residuals"]) == (200, 2) and detail["params"]
        assert detail["residual_max_m"] >= detail["residual_mean_m"] >= 0
        page = users.get(f"/api/sites/{site_id}/maps/1/poses", params={"offset": 95, "limit": 10})
        assert page["total"] == 200 and len(page["x_m"]) == len(page["frame"]) == 10
        assert page["frame"][:5] == [95, 96, 97, 98, 99] and page["frame"][5:] == [0, 1, 2, 3, 4]
        assert len(set(page["drive_id"])) == 2
        closures = users.get(f"/api/sites/{site_id}/maps/1/closures")
        assert len(closures) == detail["closures"]
        nodes = users.get(f"/api/sites/{site_id}/maps/1/nodes")
        assert len(nodes["node"]) == detail["nodes"] and nodes["edges"]
        assert all(0 <= a < b < detail["nodes"] for a, b in nodes["edges"])
        residuals = users.get(f"/api/sites/{site_id}/maps/1/residuals")
        assert len(residuals) == 2 and residuals[0]["distance_m"] >= residuals[1]["distance_m"]

    def test_unknown_versions_and_unbuildable_sites_are_refused(self, users: ApiUsers) -> None:
        site_id = users.client.post("/api/sites", json={"name": "bare"}, headers=users.auth("admin")).json()[
            "id"
        ]
        assert (
            users.client.get(f"/api/sites/{site_id}/maps/1", headers=users.auth("viewer")).status_code == 404
        )
        response = users.client.post(f"/api/sites/{site_id}/maps", json={}, headers=users.auth("surveyor"))
        assert response.status_code == 409 and users.get("/api/jobs")["total"] == 0
        viewer = users.client.post(f"/api/sites/{site_id}/maps", json={}, headers=users.auth("viewer"))
        assert viewer.status_code == 403

    def test_an_empty_mapping_drive_is_named_before_any_job(self, users: ApiUsers, site_id: int) -> None:
        drive = users.get(f"/api/drives/{users.get(f'/api/sites/{site_id}/drives')['items'][0]['id']}")
        body = {"name": "empty-run", "kind": "mapping", "fps": 10.0, "camera": drive["camera"]}
        created = users.client.post(f"/api/sites/{site_id}/drives", json=body, headers=users.auth("surveyor"))
        assert created.status_code == 201, created.text
        response = users.client.post(f"/api/sites/{site_id}/maps", json={}, headers=users.auth("surveyor"))
        assert response.status_code == 409 and "'empty-run'" in response.json()["detail"]
        assert users.get("/api/jobs")["total"] == 0


class TestOneBuildAtATime:
    def test_a_second_build_is_refused_while_one_is_queued_or_running(
        self, users: ApiUsers, site_id: int
    ) -> None:
        with users.storage.db.session() as session:  # a build no worker has taken yet
            pending = Job(kind="map.build", site_id=site_id, args={"preset": "fast"}, status="queued")
            session.add(pending)
            session.flush()
            pending_id = pending.id

        def start() -> tuple[int, str]:
            response = users.client.post(
                f"/api/sites/{site_id}/maps", json={"preset": "fast"}, headers=users.auth("surveyor")
            )
            return response.status_code, response.text

        for status in ("queued", "running"):
            with users.storage.db.session() as session:
                session.get_one(Job, pending_id).status = status
            code, text = start()
            assert code == 409, text
            assert f"job {pending_id}, {status}" in text
        assert users.get("/api/jobs")["total"] == 1
        with users.storage.db.session() as session:
            session.get_one(Job, pending_id).status = "cancelled"
        assert build(users, site_id)["result"]["version"] == 1


class TestCompareAndDelete:
    def test_moving_a_grounding_moves_the_next_version(self, users: ApiUsers, site_id: int) -> None:
        build(users, site_id)
        same = build(users, site_id)
        assert same["result"]["version"] == 2
        reused = same["result"]["stats"]
        assert (reused["segments_reused"], reused["segments_prepared"]) == (2, 0)  # no drive changed
        unchanged = users.get(f"/api/sites/{site_id}/maps/compare", params={"a": 1, "b": 2})
        assert unchanged["frames"] == 200 and unchanged["max_m"] < 1e-6
        grounding = users.get(f"/api/sites/{site_id}/groundings")["items"][0]
        moved = users.client.patch(
            f"/api/groundings/{grounding['id']}",
            json={"x": grounding["x_m"] + 3.0},
            headers=users.auth("surveyor"),
        )
        assert moved.status_code == 200
        third = build(users, site_id)["result"]["stats"]
        assert (third["segments_reused"], third["segments_prepared"]) == (
            2,
            0,
        )  # the graph alone solved again
        full = build(users, site_id, full=True)["result"]["stats"]
        assert (full["segments_reused"], full["segments_prepared"]) == (0, 2)
        same_map = users.get(f"/api/sites/{site_id}/maps/compare", params={"a": 3, "b": 4})
        assert same_map["max_m"] < 1e-6
        compared = users.get(f"/api/sites/{site_id}/maps/compare", params={"a": 2, "b": 3})
        assert compared["frames"] == 200 and (compared["only_in_a"], compared["only_in_b"]) == (0, 0)
        assert compared["max_m"] > 1.0 and compared["p95_m"] <= compared["max_m"]
        drives = users.get(f"/api/sites/{site_id}/drives")["items"]
        drive_ids = {d["id"] for d in drives if d["kind"] == "mapping"}
        assert {d["drive_id"] for d in compared["per_drive"]} == drive_ids
        assert sum(d["frames"] for d in compared["per_drive"]) == 200

    def test_a_drive_in_a_map_is_kept_until_its_versions_are_deleted(
        self, users: ApiUsers, site_id: int
    ) -> None:
        build(users, site_id)
        drives = users.get(f"/api/sites/{site_id}/drives")["items"]
        drive_id = next(d["id"] for d in drives if d["kind"] == "mapping")
        blocked = users.client.delete(f"/api/drives/{drive_id}", headers=users.auth("admin"))
        assert blocked.status_code == 409 and "map version(s) 1" in blocked.json()["detail"]
        with users.storage.db.session() as session:
            sha = session.scalars(select(MapVersion.topomap_sha256)).one()
            pieces = set(session.scalars(select(MapPiece.blob_sha256).where(MapPiece.drive_id == drive_id)))
        assert pieces and all(users.storage.blobs.exists(p) for p in pieces)
        assert users.storage.blobs.exists(sha)
        assert (
            users.client.delete(f"/api/sites/{site_id}/maps/1", headers=users.auth("surveyor")).status_code
            == 403
        )
        assert (
            users.client.delete(f"/api/sites/{site_id}/maps/1", headers=users.auth("admin")).status_code
            == 204
        )
        assert users.get(f"/api/sites/{site_id}/maps")["total"] == 0
        assert not users.storage.blobs.exists(sha)
        assert users.client.delete(f"/api/drives/{drive_id}", headers=users.auth("admin")).status_code == 204
        assert not any(users.storage.blobs.exists(p) for p in pieces)  # its kept odometry went with it


class TestLocalise:
    def test_a_stored_drive_is_localised_by_a_job_with_its_csv(self, users: ApiUsers, site_id: int) -> None:
        drives = users.get(f"/api/sites/{site_id}/drives")["items"]
        drive = next(d for d in drives if d["kind"] == "localisation")
        before = users.client.post(
            f"/api/drives/{drive['id']}/localise", json={}, headers=users.auth("surveyor")
        )
        assert users.job(before.json()["id"])["status"] == "failed"  # no map yet: the job says why
        assert "map version" in users.job(before.json()["id"])["error"]
        build(users, site_id)
        response = users.client.post(
            f"/api/drives/{drive['id']}/localise", json={"map_version": 1}, headers=users.auth("surveyor")
        )
        assert response.status_code == 202, response.text
        assert response.headers["location"] == f"/api/jobs/{response.json()['id']}"
        job = users.job(response.json()["id"])
        assert job["status"] == "succeeded", job["error"]
        assert (job["result"]["frames"], job["result"]["map_version"]) == (100, 1)
        assert job["result"]["median_error_m"] is not None
        csv = users.client.get(f"/api/jobs/{job['id']}/localisation.csv", headers=users.auth("viewer"))
        lines = csv.text.splitlines()
        assert lines[0] == ",".join(LOCALISATION_HEADER) and len(lines) == 101
        matched = LOCALISATION_HEADER.index("matched")
        assert sum(int(line.split(",")[matched]) for line in lines[1:]) == job["result"]["matched"]
        none = users.client.get(
            f"/api/jobs/{before.json()['id']}/localisation.csv", headers=users.auth("viewer")
        )
        assert none.status_code == 404
