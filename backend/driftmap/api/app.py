"""The FastAPI application: every router under ``/api``, OpenAPI at ``/docs``, the UI at ``/``.

Errors of :mod:`driftmap.errors` become JSON ``{"detail", "file", "line", "field"}`` with one status per
class: :class:`~driftmap.errors.BadRequestError` 400 (the request cannot be read: wrong content type, no
body), :class:`~driftmap.errors.BadInputError` 422 (read but unusable: a broken image, a bad CSV line),
:class:`~driftmap.errors.NotFoundError` 404, :class:`~driftmap.errors.ConflictError` 409,
:class:`~driftmap.errors.PayloadTooLargeError` 413. Request validation by FastAPI keeps its usual 422 shape.
"""

from __future__ import annotations

import logging
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse
from fastapi.staticfiles import StaticFiles

from driftmap import __version__
from driftmap.api.routes import ROUTERS
from driftmap.config import Settings, get_settings
from driftmap.errors import (
    BadInputError,
    BadRequestError,
    ConflictError,
    DriftmapError,
    NotFoundError,
    PayloadTooLargeError,
)
from driftmap.services.security import secret_key
from driftmap.store.storage import Storage

log = logging.getLogger(__name__)
FRONTEND_DIST = Path(__file__).resolve().parents[3] / "frontend" / "dist"


def status_of(error: DriftmapError) -> int:
    """The HTTP status of a driftmap error (500 for one with no mapping)."""
    for cls, code in (
        (PayloadTooLargeError, 413),
        (BadRequestError, 400),
        (BadInputError, 422),
        (NotFoundError, 404),
        (ConflictError, 409),
    ):
        if isinstance(error, cls):
            return code
    return 500


def error_body(error: DriftmapError) -> dict[str, object]:
    """The JSON body of an error response."""
    if isinstance(error, BadInputError):
        return {"detail": str(error), "file": error.file, "line": error.line, "field": error.field}
    return {"detail": str(error), "file": None, "line": None, "field": None}


async def _driftmap_error(_request: Request, exc: Exception) -> JSONResponse:
    assert isinstance(exc, DriftmapError)
    code = status_of(exc)
    if code == 500:
        log.exception("unmapped driftmap error", exc_info=exc)
    return JSONResponse(error_body(exc), status_code=code)


def create_app(settings: Settings | None = None) -> FastAPI:
    """The application for ``settings`` (the environment's when None); opens and upgrades the database."""
    settings = settings or get_settings()
    storage = Storage.open(settings)

    @asynccontextmanager
    async def lifespan(app: FastAPI) -> AsyncIterator[None]:
        yield
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
    app.add_exception_handler(DriftmapError, _driftmap_error)
    for router in ROUTERS:
        app.include_router(router, prefix="/api")
    if FRONTEND_DIST.is_dir():
        app.mount("/", StaticFiles(directory=FRONTEND_DIST, html=True), name="ui")
    return app
