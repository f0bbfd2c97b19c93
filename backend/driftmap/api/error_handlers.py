"""One mapping of :mod:`driftmap.errors` to HTTP: status codes and the JSON error body.

:class:`~driftmap.errors.BadRequestError` 400 (the request cannot be read: wrong content type, no body),
:class:`~driftmap.errors.BadInputError` 422 (read but unusable: a broken image, a bad CSV line),
:class:`~driftmap.errors.NotFoundError` 404, :class:`~driftmap.errors.ConflictError` 409,
:class:`~driftmap.errors.PayloadTooLargeError` 413. The body is ``{"detail", "file", "line", "field"}``.
"""

from __future__ import annotations

import logging

from fastapi import Request
from fastapi.responses import JSONResponse

from driftmap.errors import (
    BadInputError,
    BadRequestError,
    ConflictError,
    DriftmapError,
    NotFoundError,
    PayloadTooLargeError,
)

log = logging.getLogger(__name__)
_STATUS: tuple[tuple[type[DriftmapError], int], ...] = (
    (PayloadTooLargeError, 413),
    (BadRequestError, 400),
    (BadInputError, 422),
    (NotFoundError, 404),
    (ConflictError, 409),
)


def status_of(error: DriftmapError) -> int:
    """The HTTP status of a driftmap error (500 for one with no mapping)."""
    return next((code for cls, code in _STATUS if isinstance(error, cls)), 500)


def error_body(error: DriftmapError) -> dict[str, object]:
    """The JSON body of an error response."""
    if isinstance(error, BadInputError):
        return {"detail": str(error), "file": error.file, "line": error.line, "field": error.field}
    return {"detail": str(error), "file": None, "line": None, "field": None}


async def driftmap_error_handler(_request: Request, exc: Exception) -> JSONResponse:
    """The exception handler the app installs for :class:`~driftmap.errors.DriftmapError`."""
    assert isinstance(exc, DriftmapError)
    code = status_of(exc)
    if code == 500:
        log.error("unmapped driftmap error: %s", exc, exc_info=exc)
    return JSONResponse(error_body(exc), status_code=code)
