"""Request bodies checked before any route sees them: a size limit per kind of body, and JSON values that can
be stored.

:class:`BodyGuard` is an ASGI middleware. Every body is limited by its content type: multipart uploads by
``max_upload_bytes``, frame images (``image/jpeg``, ``image/png``) by ``max_frame_bytes``, anything else (JSON)
by ``max_json_bytes``; a declared ``Content-Length`` over the limit is a 413 at once, a body that grows over
it while being read is cut off with a 413 too.

A JSON body is then parsed once here and refused with a 422 naming the field (FastAPI's ``loc``) when it
holds a value no route could use: ``NaN`` or ``Infinity`` (not JSON, but Python's parser takes them), a
number too large for a float64 (``1e400`` parses to infinity), an integer outside 64 bits, or a string with a
lone UTF-16 surrogate (``"\\ud800"``: valid JSON, but it cannot be encoded as UTF-8 for the database or a
response) or a NUL character (PostgreSQL text cannot hold one). Bodies that are not valid JSON are passed on
for FastAPI to report.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from typing import Any

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from driftmap.api.error_handlers import error_problem, json_safe
from driftmap.api.problems import PROBLEM_MEDIA_TYPE, validation_problem
from driftmap.config import Settings
from driftmap.errors import PayloadTooLargeError
from driftmap.formats.bounds import INT64_MAX, INT64_MIN

UPLOAD_SLACK_BYTES = 64 * 1024  # multipart boundaries and small form fields around the uploaded file
_NON_FINITE = object()  # stands for a NaN or infinite number while a JSON body is checked


class _TooLargeError(Exception):
    """The body grew over the limit while being read."""


def _content_type(scope: Scope) -> str:
    for key, value in scope.get("headers", ()):
        if key == b"content-type":
            return str(value.decode("latin-1").split(";")[0].strip().lower())
    return ""


def _declared_length(scope: Scope) -> int | None:
    for key, value in scope.get("headers", ()):
        if key == b"content-length":
            text = value.decode("latin-1").strip()
            return int(text) if text.isdigit() else None
    return None


def _is_json(content_type: str) -> bool:
    return content_type in ("", "application/json") or content_type.endswith("+json")


def _parse_float(text: str) -> object:
    value = float(text)
    return value if math.isfinite(value) else _NON_FINITE


def _problems(value: object, loc: tuple[str | int, ...]) -> Iterator[dict[str, Any]]:
    """FastAPI-shaped validation errors of the values in a parsed JSON body that cannot be stored."""
    if value is _NON_FINITE:
        yield {"type": "finite_number", "loc": loc, "msg": "Input should be a finite number", "input": None}
    elif isinstance(value, int) and not isinstance(value, bool) and not INT64_MIN <= value <= INT64_MAX:
        message = f"Input should be a 64-bit integer ({INT64_MIN} to {INT64_MAX})"
        yield {"type": "int_64", "loc": loc, "msg": message, "input": None}
    elif isinstance(value, str):
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:
            message = "Input should be valid Unicode text (it holds a lone UTF-16 surrogate)"
            yield {"type": "string_unicode", "loc": loc, "msg": message, "input": json_safe(value)}
        if "\x00" in value:
            message = "Input should be text without NUL characters"
            yield {"type": "string_nul", "loc": loc, "msg": message, "input": json_safe(value)}
    elif isinstance(value, dict):
        for key, child in value.items():
            name = str(json_safe(key))
            yield from _problems(key, (*loc, name))
            yield from _problems(child, (*loc, name))
    elif isinstance(value, list):
        for index, child in enumerate(value):
            yield from _problems(child, (*loc, index))


def json_problems(body: bytes) -> list[dict[str, Any]]:
    """The validation errors of a JSON body's unusable values (see the module docstring), at most 10.

    Returns an empty list for a body that is fine or not JSON at all (FastAPI reports the latter).
    """
    try:
        parsed = json.loads(body, parse_constant=lambda _name: _NON_FINITE, parse_float=_parse_float)
    except (ValueError, RecursionError):
        return []
    found: list[dict[str, Any]] = []
    try:
        for problem in _problems(parsed, ("body",)):
            found.append(problem)
            if len(found) == 10:
                break
    except RecursionError:
        return [{"type": "json_depth", "loc": ("body",), "msg": "JSON nested too deeply", "input": None}]
    return found


class BodyGuard:
    """The ASGI middleware of the module docstring, with the limits of ``settings``."""

    def __init__(self, app: ASGIApp, settings: Settings) -> None:
        self.app = app
        self.settings = settings

    def limit_of(self, content_type: str) -> int:
        """The largest body of this content type, bytes."""
        if content_type == "multipart/form-data":
            return self.settings.max_upload_bytes + UPLOAD_SLACK_BYTES
        if content_type.startswith("image/"):
            return self.settings.max_frame_bytes
        return self.settings.max_json_bytes

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] != "http":
            await self.app(scope, receive, send)
            return
        content_type = _content_type(scope)
        limit = self.limit_of(content_type)
        declared = _declared_length(scope)
        if declared is not None and declared > limit:
            await _refuse_size(
                send, scope, f"request body of {declared} bytes is over the {limit} byte limit"
            )
            return
        if not _is_json(content_type) or declared == 0:
            await self.app(scope, _counting(receive, limit), send)
            return
        try:
            body = await _read_all(receive, limit)
        except _TooLargeError:
            await _refuse_size(send, scope, f"request body is over the {limit} byte limit")
            return
        problems = json_problems(body) if body else []
        if problems:
            await _send_problem(send, 422, validation_problem(problems, scope.get("path")))
            return
        await self.app(scope, _replay(body, receive), send)


async def _read_all(receive: Receive, limit: int) -> bytes:
    chunks: list[bytes] = []
    total = 0
    while True:
        message = await receive()
        if message["type"] != "http.request":
            break
        chunk = message.get("body", b"")
        total += len(chunk)
        if total > limit:
            raise _TooLargeError
        chunks.append(chunk)
        if not message.get("more_body", False):
            break
    return b"".join(chunks)


def _replay(body: bytes, receive: Receive) -> Receive:
    sent = False

    async def replayed() -> Message:
        nonlocal sent
        if not sent:
            sent = True
            return {"type": "http.request", "body": body, "more_body": False}
        return await receive()

    return replayed


def _counting(receive: Receive, limit: int) -> Receive:
    """``receive`` that raises PayloadTooLargeError (a 413 from the app's handler) once the body passes
    ``limit`` bytes."""
    total = 0

    async def counted() -> Message:
        nonlocal total
        message = await receive()
        if message["type"] == "http.request":
            total += len(message.get("body", b""))
            if total > limit:
                raise PayloadTooLargeError(f"request body is over the {limit} byte limit", field="body")
        return message

    return counted


async def _refuse_size(send: Send, scope: Scope, message: str) -> None:
    await _send_problem(
        send, 413, error_problem(PayloadTooLargeError(message, field="body"), scope.get("path"))
    )


async def _send_problem(send: Send, status: int, content: object) -> None:
    body = json.dumps(content, ensure_ascii=False, allow_nan=False).encode("utf-8")
    headers = [(b"content-type", PROBLEM_MEDIA_TYPE.encode()), (b"content-length", str(len(body)).encode())]
    await send({"type": "http.response.start", "status": status, "headers": headers})
    await send({"type": "http.response.body", "body": body})
