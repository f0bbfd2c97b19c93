"""Every router of the API, mounted under ``/api`` by :func:`driftmap.api.app.create_app`.

Add a router by adding one line to :data:`ROUTERS`. Each route declares its access rule through
:mod:`driftmap.api.deps` (``VIEWER``, ``SURVEYOR``, ``ADMIN`` or ``VehicleDep``); only the paths in
:data:`OPEN_PATHS` may have none, which the role-matrix test checks.
"""

from __future__ import annotations

from fastapi import APIRouter

from driftmap.api import (
    auth,
    cameras,
    drive_frames,
    drives,
    events,
    exports,
    groundings,
    health,
    jobs,
    live,
    maps,
    positions,
    sites,
    users,
    vehicles,
)

ROUTERS: list[APIRouter] = [
    health.router,
    auth.router,
    users.router,
    vehicles.router,
    cameras.router,
    live.router,
    positions.router,
    events.router,
    sites.router,
    drives.router,
    drive_frames.router,
    groundings.router,
    maps.router,
    exports.router,
    jobs.router,
]

OPEN_PATHS: frozenset[str] = frozenset({"/api/health", "/api/auth/login", "/api/auth/logout", "/metrics"})
"""Routes anyone may call without credentials."""
