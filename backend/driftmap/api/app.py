"""The FastAPI application: every router under ``/api``, OpenAPI at ``/docs``, the UI at ``/``.

Every error answer is an RFC 9457 problem (``application/problem+json``, :mod:`driftmap.api.problems`) with
driftmap's ``file``, ``line`` and ``field``; :mod:`driftmap.api.error_handlers` maps :mod:`driftmap.errors`
to statuses, one per class, and answers FastAPI's validation, routing and unexpected faults the same way.
"""

from __future__ import annotations

import gc
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from importlib import resources
from pathlib import Path

from fastapi import FastAPI
from fastapi.exceptions import RequestValidationError
from fastapi.staticfiles import StaticFiles
from starlette.exceptions import HTTPException

from driftmap import __version__
from driftmap.api import metrics, problems
from driftmap.api.body_guard import BodyGuard
from driftmap.api.deps import PrincipalCache
from driftmap.api.error_handlers import (
    driftmap_error_handler,
    http_error_handler,
    server_error_handler,
    validation_error_handler,
)
from driftmap.api.request_ids import RequestIds
from driftmap.api.routes import ROUTERS
from driftmap.api.schemas_live import add_to_openapi, event_message, position_message
from driftmap.config import Settings, get_settings
from driftmap.errors import DriftmapError
from driftmap.live.hub import InMemoryHub, LiveHub, RedisHub
from driftmap.live.ingest import LiveService
from driftmap.live.latest_frames import LatestFrames, MemoryFrames, RedisFrames
from driftmap.services.login_guard import LoginGuard
from driftmap.services.security import secret_key
from driftmap.store.storage import Storage


def ui_dir() -> Path | None:
    """The built browser UI, package data ``driftmap/ui`` (a wheel carries it; in a checkout it links to
    ``frontend/dist``), or None when it has not been built."""
    found = resources.files("driftmap") / "ui"
    return Path(str(found)).resolve() if found.is_dir() and (found / "index.html").is_file() else None


def create_app(settings: Settings | None = None) -> FastAPI:
    """The application for ``settings`` (the environment's when None); opens and upgrades the database."""
    settings = settings or get_settings()
    storage = Storage.open(settings)
    hub: LiveHub = InMemoryHub()
    frames: LatestFrames = MemoryFrames()
    if settings.redis_url:  # several API processes: watchers and latest frames shared through Redis
        hub, frames = RedisHub(settings.redis_url), RedisFrames(settings.redis_url)
    live = LiveService(
        settings,
        storage,
        hub,
        frames,
        position_message=position_message,
        event_message=event_message,
        processes=settings.live_processes,
    )

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        await live.start()
        # What the process holds once started (modules, the app, its caches) leaves the collector's full
        # passes: a long position history allocates enough objects to start one, which would otherwise walk
        # the whole heap on every such answer (bench/bench_history.py --database postgresql).
        gc.freeze()
        yield
        gc.unfreeze()
        await live.stop()
        storage.close()

    app = FastAPI(
        title="driftmap",
        version=__version__,
        description="Camera-only mapping and localisation for underground mines.",
        docs_url="/docs",
        openapi_url="/api/openapi.json",
        lifespan=lifespan,
    )
    app.state.settings = settings
    app.state.storage = storage
    app.state.secret_key = secret_key(settings)
    app.state.live = live
    app.state.principals = PrincipalCache()
    app.state.login_guard = LoginGuard.from_settings(settings)
    app.add_middleware(BodyGuard, settings=settings)
    app.state.metrics_registry = metrics.app_registry(storage, settings)
    app.add_middleware(metrics.HttpMetrics, registry=app.state.metrics_registry)
    app.add_middleware(RequestIds)  # outermost: the id is set for everything inside, errors too
    app.add_exception_handler(DriftmapError, driftmap_error_handler)
    app.add_exception_handler(RequestValidationError, validation_error_handler)
    app.add_exception_handler(HTTPException, http_error_handler)
    app.add_exception_handler(Exception, server_error_handler)
    for router in ROUTERS:
        app.include_router(router, prefix="/api", responses=problems.PROBLEM_RESPONSES)
    app.include_router(metrics.router)
    add_to_openapi(app)  # the /api/live messages (FastAPI documents no WebSocket)
    problems.add_to_openapi(app)
    ui = ui_dir()
    if ui is not None:
        app.mount("/", StaticFiles(directory=ui, html=True), name="ui")
    return app
