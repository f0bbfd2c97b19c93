"""``GET /metrics``: Prometheus text exposition of the API process (docs/operations.md, Monitoring).

* ``driftmap_http_request_duration_seconds{method, route, status}``: every request's time, labelled by the
  route's template (``/api/vehicles/{vehicle_id}/frames``), never by the values in it;
* ``driftmap_live_frames_total{status}`` and ``driftmap_localise_seconds`` (:mod:`driftmap.live.metrics`);
* read from the database at each scrape: vehicles by state (``driftmap_vehicles{state}``: reporting, lost,
  obscured, stale), jobs by status (``driftmap_jobs{status}``: the queue depth is ``status="queued"``).

Open to anyone, as ``/api/health`` is: counts only, no names, positions or tokens. Serve it on the internal
network only (or block the path at the proxy) where even counts are private.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

from fastapi import APIRouter, Request, Response
from prometheus_client import CONTENT_TYPE_LATEST, CollectorRegistry, Histogram, generate_latest
from prometheus_client.core import GaugeMetricFamily
from prometheus_client.registry import Collector
from sqlalchemy import func, select
from starlette.types import ASGIApp, Message, Receive, Scope, Send

from driftmap.config import Settings
from driftmap.live.metrics import LIVE_REGISTRY
from driftmap.services import positions as position_service
from driftmap.store.job_models import Job
from driftmap.store.storage import Storage

router = APIRouter()

_BUCKETS = (0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1.0, 2.5, 5.0, 10.0)


class StoreCollector(Collector):
    """Vehicles by state and jobs by status, counted in the database at each scrape."""

    def __init__(self, storage: Storage, settings: Settings) -> None:
        self._storage, self._settings = storage, settings

    def collect(self) -> Iterator[GaugeMetricFamily]:
        states = {"reporting": 0, "lost": 0, "obscured": 0, "stale": 0, "never": 0}
        with self._storage.db.session() as session:
            for latest in position_service.latest(session, self._settings.stale_after_s):
                p = latest.position
                if p is None:
                    states["never"] += 1
                elif latest.stale:
                    states["stale"] += 1
                elif p.lost:
                    states["lost"] += 1
                elif p.obscured:
                    states["obscured"] += 1
                else:
                    states["reporting"] += 1
            jobs = {
                str(s): int(n)
                for s, n in session.execute(select(Job.status, func.count()).group_by(Job.status))
            }
        vehicles = GaugeMetricFamily(
            "driftmap_vehicles", "Vehicles by the state of their latest position.", labels=["state"]
        )
        for state, count in states.items():
            vehicles.add_metric([state], count)
        yield vehicles
        queue = GaugeMetricFamily(
            "driftmap_jobs", "Jobs by status (queued: the queue depth).", labels=["status"]
        )
        for status in ("queued", "running", "succeeded", "failed"):
            queue.add_metric([status], jobs.get(status, 0))
        yield queue


class HttpMetrics:
    """ASGI middleware timing every HTTP request into ``registry``'s request-duration histogram."""

    def __init__(self, app: ASGIApp, registry: CollectorRegistry) -> None:
        self.app = app
        self.seconds = Histogram(
            "driftmap_http_request_duration_seconds",
            "HTTP request time, seconds, by method, route template and status.",
            ["method", "route", "status"],
            buckets=_BUCKETS,
            registry=registry,
        )

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        start, status, path = time.perf_counter(), 500, str(scope.get("path", ""))

        async def sending(message: Message) -> None:
            nonlocal status
            if message["type"] == "http.response.start":
                status = int(message["status"])
            await send(message)

        try:
            await self.app(scope, receive, sending)
        finally:
            template = _template(scope, path)
            self.seconds.labels(scope.get("method", ""), template, str(status)).observe(
                time.perf_counter() - start
            )


def _template(scope: Scope, path: str) -> str:
    """The request's ``path`` (as it came in: routing strips a router's prefix from the scope's) with each
    path parameter's segment put back as ``{name}``; "unmatched" when no route took it (an unknown path, the
    UI's static files)."""
    if scope.get("route") is None:
        return "unmatched"
    values = {str(v): k for k, v in (scope.get("path_params") or {}).items()}
    return "/".join(f"{{{values[seg]}}}" if seg in values else seg for seg in path.split("/"))


def app_registry(storage: Storage, settings: Settings) -> CollectorRegistry:
    """A registry of one app: its store collector (the HTTP histogram joins it with the middleware)."""
    registry = CollectorRegistry(auto_describe=True)
    registry.register(StoreCollector(storage, settings))
    return registry


@router.get("/metrics", include_in_schema=False)
def metrics(request: Request) -> Response:
    """Prometheus text format: this process's HTTP and live counters and the database's gauges."""
    registry: Any = request.app.state.metrics_registry
    body = generate_latest(registry) + generate_latest(LIVE_REGISTRY)
    return Response(body, media_type=CONTENT_TYPE_LATEST)
