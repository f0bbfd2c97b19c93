"""One mapping of :mod:`driftmap.errors` to HTTP, and the handlers that answer every error as a problem.

:class:`~driftmap.errors.BadRequestError` 400 (the request cannot be read: wrong content type, no body),
:class:`~driftmap.errors.BadInputError` 422 (read but unusable: a broken image, a bad CSV line),
:class:`~driftmap.errors.NotFoundError` 404, :class:`~driftmap.errors.ConflictError` 409,
:class:`~driftmap.errors.PayloadTooLargeError` 413. Every error answer, these, FastAPI's request validation
(422), routing's 404 and 405, an ``HTTPException`` (401, 403, 429) and an unexpected fault (500), is an RFC 9457
problem (:mod:`driftmap.api.problems`) with ``file``, ``line`` and ``field``.

:func:`validation_error_handler` makes every echoed ``input`` JSON-safe first: a NaN or infinity becomes its
text (``"nan"``), a lone UTF-16 surrogate its escape (``"\\ud800"``), bytes are decoded with escapes and long
inputs are cut, so the answer to a bad request never fails itself.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping

from fastapi import Request
from fastapi.exceptions import RequestValidationError
from starlette.exceptions import HTTPException
from starlette.routing import Match, Mount

from driftmap.api.problems import ProblemResponse, problem, validation_problem
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
_METHODS = ("GET", "HEAD", "POST", "PUT", "PATCH", "DELETE")
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
    """``{"detail", "file", "line", "field"}`` of an error (a live frame's refusal on the WebSocket)."""
    if isinstance(error, BadInputError):
        return {"detail": str(error), "file": error.file, "line": error.line, "field": error.field}
    return {"detail": str(error), "file": None, "line": None, "field": None}


def error_problem(error: DriftmapError, instance: str | None) -> dict[str, object]:
    """The problem body of a driftmap error."""
    if isinstance(error, BadInputError):
        return problem(
            status_of(error), str(error), instance, file=error.file, line=error.line, field=error.field
        )
    return problem(status_of(error), str(error), instance)


async def driftmap_error_handler(request: Request, exc: Exception) -> ProblemResponse:
    """The exception handler the app installs for :class:`~driftmap.errors.DriftmapError`."""
    assert isinstance(exc, DriftmapError)
    code = status_of(exc)
    if code == 500:
        log.error("unmapped driftmap error: %s", exc, exc_info=exc)
    return ProblemResponse(error_problem(exc, request.url.path), status_code=code)


def allowed_methods(request: Request) -> str:
    """The ``Allow`` of a 405: every method some route of the app takes on the request's path.

    Starlette names only the first matching route's methods, and FastAPI makes one route per path and
    method, so ``PUT /api/sites`` would be told ``Allow: GET`` although ``POST`` is allowed too. The browser
    UI's mount (every path, GET only) is left out."""
    routes = [route for route in request.app.router.routes if not isinstance(route, Mount)]
    return ", ".join(
        method
        for method in _METHODS
        if any(route.matches({**request.scope, "method": method})[0] == Match.FULL for route in routes)
    )


async def http_error_handler(request: Request, exc: Exception) -> ProblemResponse:
    """The handler for Starlette's ``HTTPException``: routing's 404 and 405, the access checks' 401 and 403,
    login throttling's 429; its headers (``WWW-Authenticate``, ``Allow``, ``Retry-After``) are kept, a 405's
    ``Allow`` completed by :func:`allowed_methods`."""
    assert isinstance(exc, HTTPException)
    detail = exc.detail if isinstance(exc.detail, str) else str(json_safe(exc.detail))
    headers = dict(exc.headers or {})
    if exc.status_code == 405 and (allowed := allowed_methods(request)):
        headers["Allow"] = allowed
    return ProblemResponse(
        problem(exc.status_code, detail, request.url.path), status_code=exc.status_code, headers=headers
    )


async def server_error_handler(request: Request, exc: Exception) -> ProblemResponse:
    """The answer to an unexpected exception (500): a problem without the exception's text, which is logged."""
    log.error("unhandled error on %s %s", request.method, request.url.path, exc_info=exc)
    return ProblemResponse(problem(500, "internal server error; see the server log", request.url.path), 500)


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


async def validation_error_handler(request: Request, exc: Exception) -> ProblemResponse:
    """The handler the app installs for FastAPI's :class:`RequestValidationError` (422)."""
    assert isinstance(exc, RequestValidationError)
    issues = json_safe(list(exc.errors()))
    assert isinstance(issues, list)
    return ProblemResponse(validation_problem(issues, request.url.path), status_code=422)
