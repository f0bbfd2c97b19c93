"""The role matrix: every route of the app with every kind of caller, read from the routes themselves.

Each HTTP route's rule comes from its dependencies (``require_roles`` marks its allowed roles, the vehicle
dependency marks vehicle-only routes), so routes added later are covered without touching this file. A
route with no rule that is not in ``OPEN_PATHS`` fails the test. The rules of the product are checked on
top: viewers only read (and acknowledge events), surveyors only write survey work, users management is admin-only.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from fastapi.dependencies.models import Dependant
from fastapi.routing import APIRoute, APIWebSocketRoute
from starlette.websockets import WebSocketDisconnect

from driftmap.api.deps import WS_CLOSE_FORBIDDEN, WS_CLOSE_UNAUTHORIZED
from driftmap.api.routes import OPEN_PATHS
from driftmap.config import Settings
from tests.api.access_helpers import Actors, make_actors

CALLERS = (None, "viewer", "surveyor", "admin", "vehicle", "other_vehicle")
USER_ROLES = ("viewer", "surveyor", "admin")
MISSING_ID = "999999"  # path parameters of user routes point at nothing, so no call changes stored data
SURVEYOR_WRITES = re.compile(
    r"/(groundings|drives|maps|map-versions|builds|jobs)(/|$)"
    r"|/sites/\{site_id\}/groundings\.csv$"  # the site's survey control file
    r"|/vehicles/\{vehicle_id\}/(camera|start)$"  # a vehicle's camera calibration and its known start
    r"|/sites/\{site_id\}/crs$"  # the site's survey coordinates
    r"|/(cameras|camera-profiles)(/|$)"  # camera calibration and stored camera profiles
)
WEBSOCKET_RULES = {"/vehicles/{vehicle_id}/stream": "vehicle", "/live": "user"}
"""WebSocket routes (their own auth, closing with 4401/4403) and who may open them."""
OWN_ACCOUNT_WRITES = frozenset({"/api/auth/password"})
"""Writes every user may make to their own account."""
CONTROL_ROOM_WRITES = frozenset({"/api/events/{event_id}/ack"})
"""Writes every user may make: the control room (viewers) acknowledges events."""
REVOKING = frozenset({"/api/auth/logout"})
"""Open routes that revoke the caller's tokens: called without credentials only (the rest still need them)."""


@dataclass(frozen=True)
class HttpRoute:
    method: str
    path: str
    dependant: Dependant


def _routes(app: Any) -> Iterator[Any]:
    """Every route of the app, inside included routers too (FastAPI keeps them lazily)."""
    for route in app.routes:
        contexts = getattr(route, "effective_route_contexts", None)
        if contexts is None:
            yield route
            continue
        yield from contexts()


def http_routes(app: Any) -> list[HttpRoute]:
    out = []
    for route in _routes(app):
        original = getattr(route, "original_route", route)
        if isinstance(original, APIRoute):
            assert route.dependant is not None
            out += [HttpRoute(m, route.path, route.dependant) for m in sorted(route.methods)]
    return out


def websocket_paths(app: Any) -> list[str]:
    return [
        original.path
        for route in _routes(app)
        if isinstance(original := getattr(route, "original_route", route), APIWebSocketRoute)
    ]


def _rule_markers(dependant: Dependant) -> tuple[frozenset[str] | None, bool]:
    """(allowed roles or None, vehicle-only) from the whole dependency tree."""
    allowed: frozenset[str] | None = None
    vehicle_only = False
    stack = [dependant]
    while stack:
        node = stack.pop()
        roles = getattr(node.call, "allowed_roles", None)
        if roles is not None:
            allowed = frozenset(roles) if allowed is None else allowed & frozenset(roles)
        vehicle_only |= bool(getattr(node.call, "vehicle_only", False))
        stack.extend(node.dependencies)
    return allowed, vehicle_only


def expected(route: HttpRoute, caller: str | None) -> str:
    """``open``, ``401`` or ``403`` for a caller on a route."""
    if route.path in OPEN_PATHS:
        return "open"
    allowed, vehicle_only = _rule_markers(route.dependant)
    assert allowed is not None or vehicle_only, f"{route.method} {route.path} has no access rule"
    if caller is None:
        return "401"
    if vehicle_only:
        return "open" if caller == "vehicle" else "403"
    if caller in ("vehicle", "other_vehicle"):
        return "403"
    assert allowed is not None
    return "open" if caller in allowed else "403"


@pytest.fixture(scope="module")
def actors(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Actors]:
    made = make_actors(Settings(data_dir=Path(tmp_path_factory.mktemp("roles")) / "data"))
    yield made
    made.client.close()


def _url(route: HttpRoute, actors: Actors) -> str:
    def fill(match: re.Match[str]) -> str:
        return str(actors.vehicle_id) if match.group(1) == "vehicle_id" else MISSING_ID

    url = re.sub(r"\{(\w+)(?::\w+)?\}", fill, route.path)
    _allowed, vehicle_only = _rule_markers(route.dependant)
    if not vehicle_only and "{vehicle_id}" in route.path:
        url = url.replace(f"/{actors.vehicle_id}", f"/{MISSING_ID}", 1)
    return url


class TestRouteMatrix:
    def test_every_route_answers_each_caller_as_the_rules_say(self, actors: Actors) -> None:
        routes = http_routes(actors.app)
        assert len(routes) >= 15
        wrong = []
        for route in routes:
            for caller in (None,) if route.path in REVOKING else CALLERS:
                response = actors.client.request(
                    route.method, _url(route, actors), headers=actors.auth(caller)
                )
                want = expected(route, caller)
                got = str(response.status_code) if response.status_code in (401, 403) else "open"
                if got != want:
                    wrong.append(
                        f"{route.method} {route.path} as {caller}: {response.status_code}, want {want}"
                    )
        assert wrong == []

    def test_every_route_has_a_rule(self, actors: Actors) -> None:
        unguarded = [
            f"{r.method} {r.path}"
            for r in http_routes(actors.app)
            if r.path not in OPEN_PATHS and _rule_markers(r.dependant) == (None, False)
        ]
        assert unguarded == []

    def test_rules_follow_the_product_roles(self, actors: Actors) -> None:
        broken = []
        for route in http_routes(actors.app):
            if route.path in OPEN_PATHS:
                continue
            allowed, vehicle_only = _rule_markers(route.dependant)
            if vehicle_only:
                if route.method == "GET":
                    broken.append(f"{route.method} {route.path}: vehicles read nothing")
                continue
            assert allowed is not None
            writes = (
                route.method not in ("GET", "HEAD")
                and route.path not in OWN_ACCOUNT_WRITES | CONTROL_ROOM_WRITES
            )
            if writes and "viewer" in allowed:
                broken.append(f"{route.method} {route.path}: viewers only read")
            if writes and "surveyor" in allowed and not SURVEYOR_WRITES.search(route.path):
                broken.append(f"{route.method} {route.path}: surveyors only write survey work")
            if route.path.startswith("/api/users") and allowed != {"admin"}:
                broken.append(f"{route.method} {route.path}: users are managed by admins")
            if not writes and not route.path.startswith("/api/users") and "viewer" not in allowed:
                broken.append(f"{route.method} {route.path}: every user may read")
        assert broken == []

    def test_bad_or_expired_tokens_are_refused(self, actors: Actors) -> None:
        for token in ("nonsense", actors.tokens["admin"] + "x", "dmv_1_guess", "dmv_x_y"):
            response = actors.client.get("/api/vehicles", headers={"Authorization": f"Bearer {token}"})
            assert response.status_code == 401, token
        assert actors.client.get("/api/vehicles").headers["www-authenticate"] == "Bearer"


class TestWebSockets:
    def test_every_websocket_route_has_a_rule(self, actors: Actors) -> None:
        assert sorted(websocket_paths(actors.app)) == sorted(WEBSOCKET_RULES)

    @pytest.mark.parametrize("caller", CALLERS)
    def test_websockets_close_for_the_wrong_caller(self, actors: Actors, caller: str | None) -> None:
        for path, rule in WEBSOCKET_RULES.items():
            url = "/api" + path.replace("{vehicle_id}", str(actors.vehicle_id))
            allowed = caller == "vehicle" if rule == "vehicle" else caller in USER_ROLES
            with actors.client.websocket_connect(url, headers=actors.auth(caller)) as ws:
                if caller is None:
                    ws.send_text("hello")  # not an auth message: refused at once
                if allowed:
                    if rule == "user":
                        assert ws.receive_json()["type"] == "snapshot"
                    else:
                        ws.send_bytes(b"short")
                        assert ws.receive_json()["status"] == "error"
                    continue
                with pytest.raises(WebSocketDisconnect) as closed:
                    ws.receive_json()
                want = WS_CLOSE_UNAUTHORIZED if caller is None else WS_CLOSE_FORBIDDEN
                assert closed.value.code == want, (path, caller)

    @pytest.mark.parametrize("path", ["/api/live", "/api/vehicles/{vehicle_id}/stream"])
    def test_a_first_auth_message_authenticates(self, actors: Actors, path: str) -> None:
        caller = "vehicle" if "stream" in path else "viewer"
        with actors.client.websocket_connect(path.format(vehicle_id=actors.vehicle_id)) as ws:
            ws.send_json({"type": "auth", "token": actors.tokens[caller]})
            if caller == "viewer":
                assert ws.receive_json()["type"] == "snapshot"
            else:
                ws.send_bytes(b"short")
                assert ws.receive_json()["status"] == "error"

    def test_a_bad_first_message_token_is_refused(self, actors: Actors) -> None:
        with actors.client.websocket_connect("/api/live") as ws:
            ws.send_json({"type": "auth", "token": "nonsense"})
            with pytest.raises(WebSocketDisconnect) as closed:
                ws.receive_json()
        assert closed.value.code == WS_CLOSE_UNAUTHORIZED

    def test_tokens_in_the_url_are_refused(self, actors: Actors) -> None:
        with (
            actors.client.websocket_connect(f"/api/live?token={actors.tokens['viewer']}") as ws,
            pytest.raises(WebSocketDisconnect) as closed,
        ):
            ws.receive_json()
        assert closed.value.code == WS_CLOSE_UNAUTHORIZED and "URL" in closed.value.reason
