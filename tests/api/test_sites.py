"""Site and survey-plan routes on a real SQLite file (TestClient; jobs in huey's immediate mode)."""

from __future__ import annotations

import time
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

from driftmap.store.job_models import Job
from tests.api.data_helpers import ApiUsers, create_site_with_survey, upload_zip
from tests.formats.test_survey_dxf import draw_plan, dxf_bytes
from tests.formats.test_survey_limits import HUGE_CIRCLE, REFUSAL_S, plan_with_binary_data
from tests.jobs.mini_site import drive_folders, zip_folder


class TestSiteCrud:
    def test_create_read_update_list_delete(self, users: ApiUsers) -> None:
        created = users.client.post(
            "/api/sites", json={"name": "north", "description": "level 3"}, headers=users.auth("admin")
        )
        assert created.status_code == 201, created.text
        site_id = created.json()["id"]
        assert users.get(f"/api/sites/{site_id}")["description"] == "level 3"
        renamed = users.client.patch(
            f"/api/sites/{site_id}", json={"name": "north-3"}, headers=users.auth("admin")
        )
        assert renamed.status_code == 200 and renamed.json()["name"] == "north-3"
        users.client.post("/api/sites", json={"name": "south"}, headers=users.auth("admin"))
        page = users.get("/api/sites", params={"limit": 1, "offset": 1})
        assert page["total"] == 2 and [s["name"] for s in page["items"]] == ["south"]
        assert users.client.delete(f"/api/sites/{site_id}", headers=users.auth("admin")).status_code == 204
        assert users.client.get(f"/api/sites/{site_id}", headers=users.auth("viewer")).status_code == 404

    def test_moments_are_answered_with_their_zone(self, users: ApiUsers) -> None:
        """Stored moments read back timezone-aware on SQLite too, as the OpenAPI date-time format says."""
        created = users.client.post("/api/sites", json={"name": "zoned"}, headers=users.auth("admin")).json()
        vehicle = users.client.post(
            "/api/vehicles", json={"name": "zoned-1", "site_id": created["id"]}, headers=users.auth("admin")
        ).json()
        listed = users.get("/api/users", role="admin")
        moments = (created["created_at"], listed[0]["created_at"], vehicle["token_rotated_at"])
        for moment in moments:
            assert datetime.fromisoformat(moment).utcoffset() == timedelta(0), moment

    def test_duplicate_names_conflict_and_only_admins_write(self, users: ApiUsers) -> None:
        assert (
            users.client.post("/api/sites", json={"name": "a"}, headers=users.auth("admin")).status_code
            == 201
        )
        again = users.client.post("/api/sites", json={"name": "a"}, headers=users.auth("admin"))
        assert again.status_code == 409
        for role in ("surveyor", "viewer"):
            response = users.client.post("/api/sites", json={"name": role}, headers=users.auth(role))
            assert response.status_code == 403
        empty = users.client.post("/api/sites", json={"name": ""}, headers=users.auth("admin"))
        assert empty.status_code == 422

    def test_deleting_a_site_removes_its_blobs(self, users: ApiUsers, mini_site: Path) -> None:
        site_id = create_site_with_survey(users, mini_site)
        job = users.job(
            upload_zip(users, site_id, "m.zip", zip_folder(drive_folders(mini_site, "map")[0])).json()["id"]
        )
        assert job["status"] == "succeeded" and users.storage.blobs.all_names()
        assert users.client.delete(f"/api/sites/{site_id}", headers=users.auth("admin")).status_code == 204
        assert users.storage.blobs.all_names() == set()
        assert users.get("/api/jobs")["total"] == 0

    def test_deleting_a_site_removes_the_blobs_of_its_failed_builds(self, users: ApiUsers) -> None:
        site_id = users.client.post("/api/sites", json={"name": "s"}, headers=users.auth("admin")).json()[
            "id"
        ]
        other_id = users.client.post("/api/sites", json={"name": "t"}, headers=users.auth("admin")).json()[
            "id"
        ]
        blobs = users.storage.blobs
        piece, block, shared = (blobs.put(f"{n}".encode())[0] for n in ("piece", "block", "shared"))
        with users.storage.db.session() as session:  # what a build that failed after its odometry leaves
            build = Job(kind="map.build", site_id=site_id, args={"preset": "fast"}, status="failed")
            session.add(build)
            session.flush()
            session.add_all(
                [
                    Job(
                        kind="map.drive",
                        site_id=site_id,
                        parent_id=build.id,
                        args={"drive_id": 1},
                        result={"piece_sha256": piece},
                        status="succeeded",
                    ),
                    Job(
                        kind="map.loops",
                        site_id=site_id,
                        parent_id=build.id,
                        args={"search_sha256": shared},
                        result={"scores_sha256": block},
                        status="succeeded",
                    ),
                    Job(kind="map.loops", site_id=other_id, args={"search_sha256": shared}, status="queued"),
                ]
            )
        assert len(blobs.all_names()) == 3
        assert users.client.delete(f"/api/sites/{site_id}", headers=users.auth("admin")).status_code == 204
        assert blobs.all_names() == {shared}  # still named by the other site's job


class TestSurvey:
    def test_layers_are_geojson_in_metres_and_simplified_by_zoom(
        self, users: ApiUsers, mini_site: Path
    ) -> None:
        site_id = create_site_with_survey(users, mini_site)
        plans = users.get(f"/api/sites/{site_id}/survey")
        assert [p["filename"] for p in plans] == ["survey.dxf"]
        full = users.get(f"/api/sites/{site_id}/survey/layers")
        assert full["tolerance_m"] == 0 and set(full["layers"]) >= {"WALLS", "CENTRELINE"}
        min_x, min_y, max_x, max_y = full["extents"]
        walls = full["layers"]["WALLS"]
        assert walls["type"] == "FeatureCollection" and walls["features"]
        for feature in walls["features"]:
            for x, y in _points(feature["geometry"]["coordinates"]):
                assert min_x - 1e-6 <= x <= max_x + 1e-6 and min_y - 1e-6 <= y <= max_y + 1e-6
        coarse = users.get(f"/api/sites/{site_id}/survey/layers", params={"zoom": 0})
        fine = users.get(f"/api/sites/{site_id}/survey/layers", params={"zoom": 12})
        assert coarse["tolerance_m"] > fine["tolerance_m"] > 0
        assert coarse["vertices"] < fine["vertices"] <= full["vertices"]
        only = users.get(
            f"/api/sites/{site_id}/survey/layers", params={"layers": "WALLS", "tolerance_m": 0.5}
        )
        assert list(only["layers"]) == ["WALLS"]

    def test_bad_layer_zoom_and_dxf_are_refused(self, users: ApiUsers, mini_site: Path) -> None:
        site_id = create_site_with_survey(users, mini_site)
        url = f"/api/sites/{site_id}/survey/layers"
        for params in (
            {"layers": "NOPE"},
            {"zoom": -1},
            {"zoom": 2, "tolerance_m": 1.0},
            {"tolerance_m": -1},
        ):
            response = users.client.get(url, params=params, headers=users.auth("viewer"))
            assert response.status_code == 422, params
        bad = users.client.post(
            f"/api/sites/{site_id}/survey",
            files={"file": ("plan.dxf", b"0\nSECTION\n2\nNONSENSE\n", "application/dxf")},
            headers=users.auth("admin"),
        )
        assert bad.status_code == 422 and bad.json()["file"].endswith("plan.dxf")
        assert len(users.get(f"/api/sites/{site_id}/survey")) == 1

    def test_a_site_without_a_plan_has_no_layers(self, users: ApiUsers) -> None:
        site_id = users.client.post("/api/sites", json={"name": "bare"}, headers=users.auth("admin")).json()[
            "id"
        ]
        response = users.client.get(f"/api/sites/{site_id}/survey/layers", headers=users.auth("viewer"))
        assert response.status_code == 404


class TestSurveyLimits:
    def upload(self, users: ApiUsers, site_id: int, name: str, data: bytes) -> Any:
        return users.client.post(
            f"/api/sites/{site_id}/survey",
            files={"file": (name, data, "application/dxf")},
            headers=users.auth("admin"),
        )

    def test_plans_over_a_limit_are_refused_quickly_and_leave_the_site_as_it_was(
        self, users: ApiUsers
    ) -> None:
        site_id = users.client.post("/api/sites", json={"name": "s"}, headers=users.auth("admin")).json()[
            "id"
        ]
        start = time.perf_counter()
        response = self.upload(users, site_id, "circle.dxf", HUGE_CIRCLE)
        assert time.perf_counter() - start < REFUSAL_S
        assert response.status_code == 422 and response.json()["file"] == "circle.dxf"
        assert "CIRCLE" in response.json()["detail"] and "survey_max_extent_m" in response.json()["detail"]
        users.client.app.state.settings.survey_max_points = 3  # type: ignore[attr-defined]
        response = self.upload(users, site_id, "lines.dxf", dxf_bytes(draw_plan("R2000")))
        assert response.status_code == 413 and "survey_max_points" in response.json()["detail"]
        assert users.get(f"/api/sites/{site_id}/survey") == []

    def test_a_windows_plan_with_binary_data_is_imported(self, users: ApiUsers) -> None:
        site_id = users.client.post("/api/sites", json={"name": "w"}, headers=users.auth("admin")).json()[
            "id"
        ]
        crlf = plan_with_binary_data().replace("\n", "\r\n").encode()
        assert self.upload(users, site_id, "win.dxf", crlf).status_code == 201
        assert list(users.get(f"/api/sites/{site_id}/survey/layers")["layers"]) == ["WALLS"]


class TestSimulate:
    def test_a_simulated_site_is_created_by_a_job(self, users: ApiUsers) -> None:
        body = {"name": "synthetic", "seed": 4, "size": "tiny", "max_frames_per_drive": 6}
        response = users.client.post("/api/sites/simulate", json=body, headers=users.auth("admin"))
        assert response.status_code == 202, response.text
        assert response.headers["location"] == f"/api/jobs/{response.json()['id']}"
        job = users.job(response.json()["id"])
        assert job["status"] == "succeeded", job["error"]
        site_id = job["result"]["site_id"]
        drives = users.get(f"/api/sites/{site_id}/drives")
        assert drives["total"] == job["result"]["drives"] >= 2
        assert {d["frame_count"] for d in drives["items"]} == {6}
        assert users.get(f"/api/sites/{site_id}/survey/layers")["layers"]
        again = users.client.post("/api/sites/simulate", json=body, headers=users.auth("admin"))
        assert again.status_code == 409


def _points(coordinates: object) -> list[tuple[float, float]]:
    if isinstance(coordinates, list) and coordinates and isinstance(coordinates[0], int | float):
        return [(float(coordinates[0]), float(coordinates[1]))]
    return [p for c in coordinates for p in _points(c)] if isinstance(coordinates, list) else []
