"""One mapping of :mod:`driftmap.errors` to HTTP: status codes and the JSON error body.

:class:`~driftmap.errors.BadRequestError` 400 (the request cannot be read: wrong content type, no body),
:class:`~driftmap.errors.BadInputError` 422 (read but unusable: a broken image, a bad CSV line),
:class:`~driftmap.errors.NotFoundError` 404, :class:`~driftmap.errors.ConflictError` 409,
:class:`~driftmap.errors.PayloadTooLargeError` 413. The body is ``{"detail", "file", "line", "field"}``.

FastAPI's own 422 (request validation) keeps its shape, ``{"detail": [{"type", "loc", "msg", "input"}]}``,
but :func:`validation_error_handler` makes every echoed ``input`` JSON-safe first: a NaN or infinity becomes
its text (``"nan"``), a lone UTF-16 surrogate its escape (``"\\ud800"``), bytes are decoded with escapes and
long inputs are cut, so the answer to a bad request never fails itself.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping

from fastapi import Request
from fastapi.exceptions import RequestValidationError
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
ECHO_MAX_CHARS = 200  # longest input text echoed back in a 422, characters
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


def json_safe(value: object, depth: int = 0) -> object:
    """``value`` as plain JSON that ``json.dumps(allow_nan=False)`` encodes to UTF-8 without failing.

    Non-finite floats become their text, strings lose lone surrogates (escaped) and are cut to
    ``ECHO_MAX_CHARS``, bytes are decoded with escapes, unknown objects become their ``str``.
    """
    if value is None or isinstance(value, bool | int):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else repr(value)
    if isinstance(value, bytes | bytearray):
        value = bytes(value[: ECHO_MAX_CHARS * 4]).decode("utf-8", "backslashreplace")
    if isinstance(value, str):
        text = value[:ECHO_MAX_CHARS]
        return text.encode("utf-8", "backslashreplace").decode("utf-8")
    if depth > 20:
        return "..."
    if isinstance(value, Mapping):
        return {str(json_safe(k, depth + 1)): json_safe(v, depth + 1) for k, v in value.items()}
    if isinstance(value, list | tuple | set | frozenset):
        return [json_safe(v, depth + 1) for v in value]
    return json_safe(str(value), depth + 1)


async def validation_error_handler(_request: Request, exc: Exception) -> JSONResponse:
    """The handler the app installs for FastAPI's :class:`RequestValidationError` (422)."""
    assert isinstance(exc, RequestValidationError)
    return JSONResponse({"detail": json_safe(list(exc.errors()))}, status_code=422)
