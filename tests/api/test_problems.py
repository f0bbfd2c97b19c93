"""Every error answer is an RFC 9457 problem, and the OpenAPI document says so for every route."""

from __future__ import annotations

from typing import Any

import httpx
import jsonschema_rs
import pytest
from fastapi.testclient import TestClient

from driftmap.api.problems import PROBLEM_MEDIA_TYPE, PROBLEM_RESPONSES, Problem
from driftmap.live.start import MAX_START_RADIUS_M
from driftmap.services import sites as site_service
from driftmap.services.users import MIN_PASSWORD_LENGTH
from tests.api.access_helpers import PASSWORD
from tests.api.data_helpers import ApiUsers

PROBLEM_REF = {"$ref": "#/components/schemas/Problem"}
NOT_PROBLEMS = {("/api/health", "get", "503")}
"""Error statuses whose body is not a problem: the health report answers 503 with its own checks."""


def _operations(document: dict[str, Any]) -> list[tuple[str, str, dict[str, Any]]]:
    return [
        (path, method, operation)
        for path, item in document["paths"].items()
        for method, operation in item.items()
    ]


def _check_problem(response: httpx.Response, status: int, document: dict[str, Any]) -> dict[str, Any]:
    """The body of ``response``, checked to be a problem of ``status`` that the OpenAPI component allows."""
    assert response.status_code == status, response.text
    assert response.headers["content-type"].split(";")[0] == PROBLEM_MEDIA_TYPE
    body: dict[str, Any] = response.json()
    Problem.model_validate(body)
    schema = {**PROBLEM_REF, "components": document["components"]}
    errors = [e.message for e in jsonschema_rs.Draft202012Validator(schema).iter_errors(body)]
    assert not errors, (errors, body)
    component = document["components"]["schemas"]["Problem"]
    assert set(component["required"]) <= set(body) <= set(component["properties"]), body
    assert body["status"] == status and body["title"] and body["detail"]
    assert body["instance"] == response.request.url.path
    return body


@pytest.fixture
def document(users: ApiUsers) -> dict[str, Any]:
    openapi: dict[str, Any] = users.app.openapi()
    return openapi


class TestTheDocument:
    def test_every_documented_error_is_a_problem(self, document: dict[str, Any]) -> None:
        operations = _operations(document)
        assert len(operations) > 50
        for path, method, operation in operations:
            responses = operation["responses"]
            assert {str(code) for code in PROBLEM_RESPONSES} <= set(responses), (path, method)
            for code, response in responses.items():
                if int(code) < 400 or (path, method, code) in NOT_PROBLEMS:
                    continue
                assert response["content"] == {PROBLEM_MEDIA_TYPE: {"schema": PROBLEM_REF}}, (
                    path,
                    method,
                    code,
                )

    def test_bounds_the_services_check_are_documented(self, document: dict[str, Any]) -> None:
        """A value the schema allows is not refused for a bound the schema does not state (schemathesis's
        positive-data check found these)."""
        schemas = document["components"]["schemas"]
        radius = schemas["StartRequest"]["properties"]["radius_m"]
        assert (radius["minimum"], radius["maximum"]) == (0.0, MAX_START_RADIUS_M)
        for schema, field in (("UserCreate", "password"), ("PasswordChange", "new_password")):
            assert schemas[schema]["properties"][field]["minLength"] == MIN_PASSWORD_LENGTH, schema
        reset = schemas["UserUpdate"]["properties"]["password"]["anyOf"][0]
        assert reset["minLength"] == MIN_PASSWORD_LENGTH

    def test_no_route_keeps_fastapis_validation_schema(self, document: dict[str, Any]) -> None:
        assert "HTTPValidationError" not in document["components"]["schemas"]

    def test_every_202_names_its_location(self, document: dict[str, Any]) -> None:
        accepted = [(p, m, o) for p, m, o in _operations(document) if "202" in o["responses"]]
        assert len(accepted) == 5
        for path, method, operation in accepted:
            assert "Location" in operation["responses"]["202"]["headers"], (path, method)


class TestRealAnswers:
    def test_validation_422(self, users: ApiUsers, document: dict[str, Any]) -> None:
        response = users.client.get("/api/jobs?limit=0", headers=users.auth("viewer"))
        body = _check_problem(response, 422, document)
        assert body["field"] == "limit" and body["errors"][0]["loc"] == ["query", "limit"]
        assert body["detail"].startswith("limit: ")

    def test_body_guard_422_names_the_field(self, users: ApiUsers, document: dict[str, Any]) -> None:
        response = users.client.post(
            "/api/sites",
            content='{"name": "a", "description": NaN}',
            headers={**users.auth("admin"), "Content-Type": "application/json"},
        )
        assert _check_problem(response, 422, document)["field"] == "description"

    def test_domain_and_routing_404(self, users: ApiUsers, document: dict[str, Any]) -> None:
        missing = users.client.get("/api/sites/424242", headers=users.auth("viewer"))
        assert "424242" in _check_problem(missing, 404, document)["detail"]
        _check_problem(users.client.get("/api/no-such-thing"), 404, document)

    def test_405_keeps_allow(self, users: ApiUsers, document: dict[str, Any]) -> None:
        response = users.client.delete("/api/health")
        _check_problem(response, 405, document)
        assert "GET" in response.headers["allow"]

    @pytest.mark.parametrize(
        ("method", "url", "template"),
        [
            ("PUT", "/api/sites", "/api/sites"),
            ("POST", "/api/sites/1", "/api/sites/{site_id}"),
            ("POST", "/api/vehicles/1/camera", "/api/vehicles/{vehicle_id}/camera"),
        ],
    )
    def test_405_allows_every_method_of_the_path(
        self, users: ApiUsers, document: dict[str, Any], method: str, url: str, template: str
    ) -> None:
        response = users.client.request(method, url, headers=users.auth("admin"))
        _check_problem(response, 405, document)
        documented = {m.upper() for m in document["paths"][template]}
        assert documented <= set(response.headers["allow"].split(", ")), response.headers["allow"]

    def test_409(self, users: ApiUsers, document: dict[str, Any]) -> None:
        body = {"username": "viewer", "password": "longenough1", "role": "viewer"}
        response = users.client.post("/api/users", json=body, headers=users.auth("admin"))
        assert "already exists" in _check_problem(response, 409, document)["detail"]

    def test_413(self, users: ApiUsers, document: dict[str, Any]) -> None:
        limit = users.app.state.settings.max_json_bytes
        response = users.client.post(
            "/api/sites",
            content=b" " * (limit + 1),
            headers={**users.auth("admin"), "Content-Type": "application/json"},
        )
        assert _check_problem(response, 413, document)["field"] == "body"

    def test_401_keeps_www_authenticate(self, users: ApiUsers, document: dict[str, Any]) -> None:
        response = users.client.get("/api/sites")
        _check_problem(response, 401, document)
        assert response.headers["www-authenticate"].startswith("Bearer")

    def test_403(self, users: ApiUsers, document: dict[str, Any]) -> None:
        response = users.client.post("/api/sites", json={"name": "x"}, headers=users.auth("viewer"))
        _check_problem(response, 403, document)

    def test_400_names_the_file(self, users: ApiUsers, document: dict[str, Any]) -> None:
        site = users.client.post("/api/sites", json={"name": "north"}, headers=users.auth("admin")).json()
        response = users.client.post(
            f"/api/sites/{site['id']}/drives/zip",
            files={"file": ("drive.zip", b"not a zip at all", "application/zip")},
            headers=users.auth("surveyor"),
        )
        assert _check_problem(response, 400, document)["file"] == "drive.zip"

    def test_422_of_a_file_names_file_line_and_field(self, users: ApiUsers, document: dict[str, Any]) -> None:
        site = users.client.post("/api/sites", json={"name": "north"}, headers=users.auth("admin")).json()
        response = users.client.put(
            f"/api/sites/{site['id']}/groundings.csv",
            files={"file": ("control.csv", b"drive,frame,station,x,y,enabled\nnowhere,1,,0,0,true\n")},
            headers=users.auth("surveyor"),
        )
        body = _check_problem(response, 422, document)
        assert (body["file"], body["line"], body["field"]) == ("control.csv", 2, "drive")

    def test_429_keeps_retry_after(self, users: ApiUsers, document: dict[str, Any]) -> None:
        limit = users.app.state.settings.login_max_failures_per_user
        wrong = {"username": "viewer", "password": "not the password"}
        assert {users.client.post("/api/auth/login", json=wrong).status_code for _ in range(limit)} == {401}
        response = users.client.post("/api/auth/login", json={"username": "viewer", "password": PASSWORD})
        assert "too many failed logins" in _check_problem(response, 429, document)["detail"]
        assert int(response.headers["retry-after"]) > 0

    def test_500_hides_the_fault(
        self, users: ApiUsers, document: dict[str, Any], monkeypatch: pytest.MonkeyPatch
    ) -> None:
        def broken(*_args: object, **_kwargs: object) -> object:
            raise RuntimeError("secret internals")

        monkeypatch.setattr(site_service, "list_sites", broken)
        with TestClient(users.app, raise_server_exceptions=False) as client:
            response = client.get("/api/sites", headers=users.auth("viewer"))
        body = _check_problem(response, 500, document)
        assert "secret internals" not in response.text and "server log" in body["detail"]
