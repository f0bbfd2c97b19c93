"""Bad input on the real app (TestClient on a real SQLite file): every value the database or the encoder
cannot take is a 422 (or 413) naming its field, never a 500; sizes are checked from headers, not by decoding."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import httpx
import pytest
from sqlalchemy import update

from driftmap.config import Settings
from driftmap.errors import BadInputError
from driftmap.services import users as user_service
from driftmap.services.users import MAX_PASSWORD_LENGTH
from driftmap.store.models import Drive
from tests.api.data_helpers import ApiUsers, api_users, create_site_with_survey
from tests.image_bombs import zero_png
from tests.jobs.mini_site import drive_folders

HUGE = 2**63  # one past the largest 64-bit integer
REFUSED_WITHIN_S = 10.0  # a guard against the defects fixed (a minute and gigabytes), not a speed figure


def _loc(response: httpx.Response) -> list[Any]:
    """The ``loc`` of the first validation error of a 422 problem."""
    assert response.status_code == 422, response.text
    return list(response.json()["errors"][0]["loc"])


def _post_json(users: ApiUsers, url: str, text: str, role: str = "admin") -> httpx.Response:
    """POST a raw JSON text (``json=`` would refuse NaN and lone surrogates on the client side)."""
    headers = {**users.auth(role), "Content-Type": "application/json"}
    return users.client.post(url, content=text.encode("utf-8", "surrogatepass"), headers=headers)


@pytest.fixture
def survey_site(users: ApiUsers, mini_site: Path) -> int:
    """A site with the mini site's survey, no drives."""
    return create_site_with_survey(users, mini_site)


@pytest.fixture
def camera(mini_site: Path) -> dict[str, Any]:
    block: dict[str, Any] = json.loads((drive_folders(mini_site, "map")[0] / "drive.json").read_text())[
        "camera"
    ]
    return block


@pytest.fixture
def empty_drive(users: ApiUsers, survey_site: int, camera: dict[str, Any]) -> int:
    body = {"name": "rec", "kind": "localisation", "fps": 10.0, "camera": camera}
    created = users.client.post(f"/api/sites/{survey_site}/drives", json=body, headers=users.auth("surveyor"))
    assert created.status_code == 201, created.text
    drive_id: int = created.json()["id"]
    return drive_id


PATH_AND_QUERY = [
    (f"/api/sites/{HUGE}", ["path", "site_id"]),
    (f"/api/drives/{HUGE}/frames/1", ["path", "drive_id"]),
    (f"/api/drives/1/frames/{HUGE}", ["path", "index"]),
    (f"/api/jobs/{HUGE}", ["path", "job_id"]),
    (f"/api/sites/1/drives?offset={HUGE}", ["query", "offset"]),
    (f"/api/positions?since={HUGE}", ["query", "since"]),
    (f"/api/vehicles?site_id={-HUGE - 1}", ["query", "site_id"]),
    (f"/api/users/{HUGE}", ["path", "user_id"]),
    (f"/api/sites/1/maps/compare?a={HUGE}&b=1", ["query", "a"]),
]


class TestIntegersBeyond64Bits:
    def test_path_query_and_body_name_the_field(self, users: ApiUsers) -> None:
        for url, loc in PATH_AND_QUERY:
            assert _loc(users.client.get(url, headers=users.auth("admin"))) == loc, url
        response = _post_json(users, "/api/vehicles", f'{{"name": "v", "site_id": {HUGE * 10**6}}}')
        assert _loc(response) == ["body", "site_id"]
        headers = {"Authorization": "Bearer dmv_99999999999999999999_x"}  # a vehicle token's id
        assert users.client.get("/api/sites", headers=headers).status_code == 401


BEYOND_THE_DATABASE = 2**31  # one past PostgreSQL's integer, the type of ids and frame numbers
IN_PATH_AND_QUERY = [
    (f"/api/sites/{BEYOND_THE_DATABASE}", ["path", "site_id"]),
    (f"/api/drives/1/frames/{BEYOND_THE_DATABASE}", ["path", "index"]),
    (f"/api/users/{BEYOND_THE_DATABASE}", ["path", "user_id"]),
    (f"/api/vehicles?site_id={BEYOND_THE_DATABASE}", ["query", "site_id"]),
    (f"/api/positions?since={BEYOND_THE_DATABASE}", ["query", "since"]),
    (f"/api/sites/1/maps/compare?a=1&b={BEYOND_THE_DATABASE}", ["query", "b"]),
]


class TestIntegersBeyondTheDatabase:
    """Integers that fit 64 bits but not the database's ``integer`` columns (a 500 on PostgreSQL)."""

    def test_path_query_and_body_name_the_field(self, users: ApiUsers) -> None:
        for url, loc in IN_PATH_AND_QUERY:
            assert _loc(users.client.get(url, headers=users.auth("admin"))) == loc, url
        response = _post_json(users, "/api/vehicles", f'{{"name": "v", "site_id": {BEYOND_THE_DATABASE}}}')
        assert _loc(response) == ["body", "site_id"]

    def test_a_vehicle_token_with_such_an_id_is_not_valid(self, users: ApiUsers) -> None:
        headers = {"Authorization": f"Bearer dmv_{BEYOND_THE_DATABASE}_x"}
        assert users.client.get("/api/sites", headers=headers).status_code == 401


class TestNumbersThatAreNotFinite:
    def test_fps_is_named_and_the_answer_encodes(
        self, users: ApiUsers, survey_site: int, camera: dict[str, Any]
    ) -> None:
        for fps in ("NaN", "Infinity", "-Infinity", "1e400"):
            text = f'{{"name": "d", "kind": "mapping", "fps": {fps}, "camera": {json.dumps(camera)}}}'
            response = _post_json(users, f"/api/sites/{survey_site}/drives", text)
            assert _loc(response) == ["body", "fps"], fps
        echoed = users.client.get(
            "/api/vehicles/1/positions", params={"start": "nan"}, headers=users.auth("viewer")
        )
        assert _loc(echoed) == ["query", "start"]
        assert echoed.json()["errors"][0]["input"] == "nan"

    def test_a_first_drive_frame_with_a_bad_t_is_named(
        self, users: ApiUsers, empty_drive: int, mini_site: Path
    ) -> None:
        frame = sorted((drive_folders(mini_site, "loc")[0] / "frames").iterdir())[0].read_bytes()
        for t in ("nan", "inf", "-inf", "1e308"):
            response = users.client.post(
                f"/api/drives/{empty_drive}/frames",
                params={"t": t},
                content=frame,
                headers={**users.auth("surveyor"), "Content-Type": "image/png"},
            )
            assert _loc(response) == ["query", "t"], t
        assert users.get(f"/api/drives/{empty_drive}")["frame_count"] == 0


class TestText:
    def test_lone_surrogates_and_nul_characters_are_named(self, users: ApiUsers) -> None:
        response = _post_json(users, "/api/sites", '{"name": "\\ud800"}')
        assert _loc(response) == ["body", "name"]
        assert response.json()["errors"][0]["input"] == "\\ud800"
        nul = _post_json(users, "/api/sites", '{"name": "a", "description": "x\\u0000"}')
        assert _loc(nul) == ["body", "description"]

    def test_names_and_descriptions_have_a_length_limit(self, users: ApiUsers) -> None:
        long_description = users.client.post(
            "/api/sites", json={"name": "a", "description": "d" * 10_001}, headers=users.auth("admin")
        )
        assert _loc(long_description) == ["body", "description"]
        assert len(long_description.text) < 2000  # the echoed input is cut
        line_break = users.client.post("/api/sites", json={"name": "a\r\nb"}, headers=users.auth("admin"))
        assert _loc(line_break) == ["body", "name"]

    def test_passwords_have_a_length_limit(self, users: ApiUsers) -> None:
        huge = "p" * (MAX_PASSWORD_LENGTH + 1)
        login = users.client.post("/api/auth/login", json={"username": "admin", "password": huge})
        assert _loc(login) == ["body", "password"]
        create = users.client.post(
            "/api/users",
            json={"username": "long", "password": huge, "role": "viewer"},
            headers=users.auth("admin"),
        )
        assert _loc(create) == ["body", "password"]
        assert "long" not in [u["username"] for u in users.get("/api/users", role="admin")]
        with users.storage.db.session() as session, pytest.raises(BadInputError, match="1024") as refused:
            user_service.create_user(session, "long", huge, "viewer")  # the CLI's way in
        assert refused.value.field == "password"

    def test_groundings_csv_of_any_drive_name_downloads(self, users: ApiUsers, empty_drive: int) -> None:
        for name in ("坑道", "east\r\nSet-Cookie: x=1", 'a"b\\c'):
            with users.storage.db.session() as session:  # names from drive.json may hold anything
                session.execute(update(Drive).where(Drive.id == empty_drive).values(name=name))
            response = users.client.get(
                f"/api/drives/{empty_drive}/groundings.csv", headers=users.auth("viewer")
            )
            assert response.status_code == 200, response.text
            disposition = response.headers["content-disposition"]
            assert disposition.isascii() and "\r" not in disposition and "\n" not in disposition
            encoded = disposition.split("filename*=UTF-8''")[1]
            assert httpx.URL(f"http://x/?n={encoded}").params["n"] == f"{name}-groundings.csv"


class TestBodySize:
    def test_a_json_body_over_the_limit_is_413(self, tmp_path: Path) -> None:
        users = api_users(Settings(data_dir=tmp_path / "data", max_json_bytes=1000))
        try:
            response = users.client.post(
                "/api/sites", json={"name": "a", "description": "d" * 2000}, headers=users.auth("admin")
            )
            assert response.status_code == 413 and response.json()["field"] == "body"
            ok = users.client.post("/api/sites", json={"name": "a"}, headers=users.auth("admin"))
            assert ok.status_code == 201
        finally:
            users.client.close()


class TestCameraAndFrameSizes:
    def test_an_absurd_camera_is_named(
        self, users: ApiUsers, survey_site: int, camera: dict[str, Any]
    ) -> None:
        body = {"name": "d", "fps": 10.0, "camera": {**camera, "width": 100_000, "height": 100_000}}
        response = users.client.post(
            f"/api/sites/{survey_site}/drives", json=body, headers=users.auth("admin")
        )
        assert _loc(response) == ["body", "camera", "width"]
        created = users.client.post(
            "/api/vehicles", json={"name": "v", "site_id": survey_site}, headers=users.auth("admin")
        )
        vehicle_id = created.json()["id"]
        put = users.client.put(
            f"/api/vehicles/{vehicle_id}/camera",
            json={**camera, "width": 100_000, "height": 100_000},
            headers=users.auth("admin"),
        )
        assert put.status_code == 422 and put.json()["field"] == "camera.width"

    def test_a_drive_frame_bomb_is_refused_from_its_header(self, users: ApiUsers, empty_drive: int) -> None:
        bomb = zero_png(30_000, 30_000)
        start = time.perf_counter()
        response = users.client.post(
            f"/api/drives/{empty_drive}/frames",
            params={"t": 0.0},
            content=bomb,
            headers={**users.auth("surveyor"), "Content-Type": "image/png"},
        )
        assert time.perf_counter() - start < REFUSED_WITHIN_S
        assert response.status_code == 422 and "30000x30000" in response.json()["detail"]
