"""Request dependencies: settings, storage, a database session per request, and who is calling.

Credentials come as ``Authorization: Bearer <token>``, or the ``driftmap_token`` cookie set at login; a
WebSocket without either sends ``{"type": "auth", "token": "..."}`` as its first message (browsers cannot
set headers on WebSockets; see :mod:`driftmap.api.ws_auth`). Tokens never travel in URLs. A token is either
a user's login token or a vehicle token (``dmv_...``). A login token is accepted only while its user is
active and its token generation is the user's current one (:mod:`driftmap.services.security`).

Roles: ``viewer`` reads (GET) and acknowledges the control room's events; ``surveyor`` also edits groundings, imports drives and builds maps; ``admin``
may do everything (users, vehicles, sites). A vehicle token may only post frames for its own vehicle.
No credentials give 401, the wrong role or a vehicle token elsewhere 403.

Routers declare their rule with ``dependencies=[Depends(VIEWER)]``, ``Depends(SURVEYOR)``,
``Depends(ADMIN)`` or a :data:`VehicleDep` parameter; the role test reads these from every route.
"""

from __future__ import annotations

import time
from collections.abc import Awaitable, Callable, Iterator
from dataclasses import dataclass
from enum import StrEnum
from typing import Annotated

from fastapi import Depends, HTTPException, Path, Request, status
from sqlalchemy.orm import Session
from starlette.concurrency import run_in_threadpool
from starlette.requests import HTTPConnection

from driftmap.api.input_types import Id
from driftmap.config import Settings
from driftmap.services import security
from driftmap.store.access_models import User, Vehicle
from driftmap.store.storage import Storage

TOKEN_COOKIE = "driftmap_token"
WS_CLOSE_UNAUTHORIZED = 4401
WS_CLOSE_FORBIDDEN = 4403
AUTH_CACHE_S = 2.0  # how long a checked token is trusted without looking it up again, seconds


class Role(StrEnum):
    """What a user may do; see the module docstring."""

    admin = "admin"
    surveyor = "surveyor"
    viewer = "viewer"


@dataclass(frozen=True)
class Principal:
    """Who is calling: a logged-in user (with a role) or a vehicle (with its site)."""

    kind: str  # "user" or "vehicle"
    id: int
    name: str
    role: Role | None = None
    site_id: int | None = None


def _settings(request: HTTPConnection) -> Settings:
    settings: Settings = request.app.state.settings
    return settings


def _storage(request: HTTPConnection) -> Storage:
    storage: Storage = request.app.state.storage
    return storage


SettingsDep = Annotated[Settings, Depends(_settings)]
StorageDep = Annotated[Storage, Depends(_storage)]


def _session(storage: StorageDep) -> Iterator[Session]:
    with storage.db.session() as session:
        yield session


SessionDep = Annotated[Session, Depends(_session, scope="function")]
"""A session committed when the handler returns (before the response is sent), rolled back if it raises."""


def token_of(conn: HTTPConnection) -> str | None:
    """The bearer token or cookie token of a request."""
    header = conn.headers.get("authorization", "")
    scheme, _, value = header.partition(" ")
    if scheme.lower() == "bearer" and value.strip():
        return value.strip()
    cookie = conn.cookies.get(TOKEN_COOKIE)
    return cookie or None


def principal_of(conn: HTTPConnection) -> Principal | None:
    """Who the credentials of ``conn`` belong to; None when there are none or they are not valid."""
    token = token_of(conn)
    return None if token is None else principal_of_token(conn, token)


def principal_of_token(conn: HTTPConnection, token: str) -> Principal | None:
    """Who ``token`` belongs to (a database lookup); None when it is not valid."""
    storage = _storage(conn)
    vehicle_id = security.vehicle_id_of_token(token)
    with storage.db.session() as session:
        if vehicle_id is not None:
            vehicle = session.get(Vehicle, vehicle_id)
            if vehicle is None or vehicle.token_sha256 != security.token_sha256(token):
                return None
            return Principal("vehicle", vehicle.id, vehicle.name, site_id=vehicle.site_id)
        key: bytes = conn.app.state.secret_key
        claims = security.read_token(key, token)
        user = session.get(User, claims.user_id) if claims is not None else None
        if user is None or claims is None:
            return None
        if user.disabled_at is not None or user.token_generation != claims.generation:
            return None  # disabled, or the token was revoked
        return Principal("user", user.id, user.username, role=Role(user.role))


class PrincipalCache:
    """Token -> principal answers of the last ``ttl_s`` seconds, so frames do not each hit the database.

    The routes that change users or vehicle tokens clear it, so this process sees a change at once; another
    server process sees it within ``ttl_s``.
    """

    def __init__(self, ttl_s: float = AUTH_CACHE_S, max_entries: int = 10000) -> None:
        self.ttl_s = ttl_s
        self.max_entries = max_entries
        self._entries: dict[str, tuple[Principal | None, float]] = {}

    def get(self, token: str) -> tuple[bool, Principal | None]:
        """(found, principal) for ``token``."""
        entry = self._entries.get(token)
        if entry is None or time.monotonic() - entry[1] > self.ttl_s:
            return False, None
        return True, entry[0]

    def put(self, token: str, principal: Principal | None) -> None:
        if len(self._entries) >= self.max_entries:
            self._entries.clear()
        self._entries[token] = (principal, time.monotonic())

    def clear(self) -> None:
        self._entries.clear()


async def cached_principal(conn: HTTPConnection, token: str | None = None) -> Principal | None:
    """Who ``token`` (default: the request's :func:`token_of`) belongs to, through the app's
    :class:`PrincipalCache` (the lookup in a worker thread)."""
    token = token if token is not None else token_of(conn)
    if token is None:
        return None
    cache: PrincipalCache = conn.app.state.principals
    found, principal = cache.get(token)
    if not found:
        principal = await run_in_threadpool(principal_of_token, conn, token)
        cache.put(token, principal)
    return principal


def forget_principals(conn: HTTPConnection) -> None:
    """Drop cached credentials (after a user or vehicle token changed)."""
    cache: PrincipalCache = conn.app.state.principals
    cache.clear()


def _unauthorized() -> HTTPException:
    return HTTPException(
        status.HTTP_401_UNAUTHORIZED,
        "not authenticated: log in or send a token",
        {"WWW-Authenticate": "Bearer"},
    )


async def _current_principal(request: Request) -> Principal | None:
    return await cached_principal(request)


async def _current_user(principal: Annotated[Principal | None, Depends(_current_principal)]) -> Principal:
    if principal is None:
        raise _unauthorized()
    if principal.kind != "user":
        raise HTTPException(status.HTTP_403_FORBIDDEN, "a vehicle token may only post its own frames")
    return principal


CurrentUserDep = Annotated[Principal, Depends(_current_user)]
"""The logged-in user (any role); 401 without credentials, 403 for a vehicle token."""


def require_roles(*roles: Role) -> Callable[[Principal], Awaitable[Principal]]:
    """A dependency that lets through users with one of ``roles`` (admins always); 403 for others.

    Use as ``dependencies=[Depends(require_roles(Role.surveyor))]`` or through :data:`VIEWER`,
    :data:`SURVEYOR`, :data:`ADMIN`.
    """
    allowed = frozenset({*roles, Role.admin})

    async def check(user: CurrentUserDep) -> Principal:
        if user.role not in allowed:
            names = ", ".join(sorted(allowed))
            raise HTTPException(status.HTTP_403_FORBIDDEN, f"this needs one of the roles: {names}")
        return user

    check.allowed_roles = allowed  # type: ignore[attr-defined]  # read by the role-matrix test
    return check


VIEWER = require_roles(Role.viewer, Role.surveyor)
"""Read access, and acknowledging events in the control room: every logged-in user."""
SURVEYOR = require_roles(Role.surveyor)
"""Survey work: groundings, drive imports, map builds (and admins)."""
ADMIN = require_roles()
"""Administration: users, vehicles, sites."""

ViewerDep = Annotated[Principal, Depends(VIEWER)]
SurveyorDep = Annotated[Principal, Depends(SURVEYOR)]
AdminDep = Annotated[Principal, Depends(ADMIN)]


async def _vehicle(
    vehicle_id: Annotated[Id, Path(description="The vehicle's id.")],
    principal: Annotated[Principal | None, Depends(_current_principal)],
) -> Principal:
    if principal is None:
        raise _unauthorized()
    if principal.kind != "vehicle" or principal.id != vehicle_id:
        raise HTTPException(status.HTTP_403_FORBIDDEN, f"only vehicle {vehicle_id}'s own token may post here")
    return principal


_vehicle.vehicle_only = True  # type: ignore[attr-defined]  # read by the role-matrix test
VehicleDep = Annotated[Principal, Depends(_vehicle)]
"""The vehicle of the path's ``vehicle_id``, authenticated by its own token."""
