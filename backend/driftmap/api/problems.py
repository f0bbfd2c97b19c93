"""Error answers as RFC 9457 problem details (``application/problem+json``), and their OpenAPI documentation.

Every error the API answers, whatever raised it (a :class:`~driftmap.errors.DriftmapError`, FastAPI's request
validation, routing's 404/405, an ``HTTPException``, the body limits, an unexpected fault), has one body,
:class:`Problem`: the standard members ``type`` (``about:blank``: the status says it all), ``title`` (the
status's phrase), ``status``, ``detail`` (what is wrong, for a person) and ``instance`` (the request path),
plus driftmap's ``file``, ``line`` and ``field`` naming the input at fault (null when there is none) and, for a
request that failed validation, ``errors`` (FastAPI's ``{type, loc, msg, input}`` list).

:data:`PROBLEM_RESPONSES` documents these statuses for every route (the app passes it to each router), and
:func:`add_to_openapi` files them under ``application/problem+json``.
"""

from __future__ import annotations

from collections.abc import Sequence
from http import HTTPStatus
from typing import Any

from fastapi import FastAPI
from pydantic import BaseModel, Field
from starlette.responses import JSONResponse

PROBLEM_MEDIA_TYPE = "application/problem+json"
_LOCATION_KINDS = ("body", "query", "path", "header", "cookie")


class ValidationIssue(BaseModel):
    """One reason a request failed validation (FastAPI's shape)."""

    type: str = Field(description="A short code for the kind of failure, e.g. ``missing``, ``int_parsing``.")
    loc: list[str | int] = Field(description="Where: ``body``, ``query``, ``path``... then the field's path.")
    msg: str
    input: Any = Field(default=None, description="The value at fault, made JSON-safe and cut to 200 chars.")


class Problem(BaseModel):
    """An error answer: RFC 9457 problem details with driftmap's ``file``, ``line`` and ``field``."""

    type: str = Field(default="about:blank", description="A URI naming the kind of problem.")
    title: str = Field(description="The HTTP status's phrase, e.g. ``Not Found``.")
    status: int = Field(ge=400, le=599, description="The HTTP status code.")
    detail: str = Field(description="What is wrong, in words a user can act on.")
    instance: str | None = Field(default=None, description="The path of the request that failed.")
    file: str | None = Field(default=None, description="The file at fault (an upload, a member of a zip).")
    line: int | None = Field(default=None, description="1-based line inside ``file``.")
    field: str | None = Field(default=None, description="The field, column or parameter at fault.")
    errors: list[ValidationIssue] | None = Field(
        default=None, description="Each reason of a request validation failure (422 only)."
    )


class ProblemResponse(JSONResponse):
    """A JSON response served as ``application/problem+json``."""

    media_type = PROBLEM_MEDIA_TYPE


def _phrase(status: int) -> str:
    try:
        return HTTPStatus(status).phrase
    except ValueError:
        return "Error"


def problem(
    status: int,
    detail: str,
    instance: str | None,
    *,
    file: str | None = None,
    line: int | None = None,
    field: str | None = None,
    errors: Sequence[dict[str, Any]] | None = None,
) -> dict[str, Any]:
    """The :class:`Problem` body (plain JSON) of an error answer."""
    body: dict[str, Any] = {
        "type": "about:blank",
        "title": _phrase(status),
        "status": status,
        "detail": detail,
        "instance": instance,
        "file": file,
        "line": line,
        "field": field,
    }
    if errors is not None:
        body["errors"] = list(errors)
    return body


def _where(loc: object) -> str:
    parts = [str(p) for p in loc] if isinstance(loc, list | tuple) else []
    return ".".join(parts[1:] if parts and parts[0] in _LOCATION_KINDS else parts)


def validation_problem(issues: Sequence[dict[str, Any]], instance: str | None) -> dict[str, Any]:
    """The 422 :class:`Problem` of a request that failed validation: ``issues`` (FastAPI's ``{type, loc, msg,
    input}``, JSON-safe) under ``errors``, a ``detail`` of ``"where: msg; ..."`` and the first one's ``field``."""
    kept = [{k: issue.get(k) for k in ("type", "loc", "msg", "input")} for issue in issues]
    texts = [f"{_where(i['loc'])}: {i['msg']}" if _where(i["loc"]) else str(i["msg"]) for i in kept]
    field = (_where(kept[0]["loc"]) or None) if kept else None
    detail = "; ".join(texts) or "the request is not valid"
    return problem(422, detail, instance, field=field, errors=kept)


_DESCRIPTIONS: dict[int, str] = {
    400: "The request cannot be read (wrong content type, no body).",
    401: "No valid credentials (see ``WWW-Authenticate``).",
    403: "The credentials do not allow this.",
    404: "The thing named in the path does not exist.",
    409: "The request clashes with what is stored.",
    413: "The body, or a value in it, is over a configured limit.",
    422: "The request was read but a value in it cannot be used.",
    500: "A fault of the server.",
}


def problem_responses(*codes: int, descriptions: dict[int, str] | None = None) -> dict[int | str, Any]:
    """An OpenAPI ``responses=`` mapping documenting ``codes`` as :class:`Problem` answers."""
    named = {**_DESCRIPTIONS, **(descriptions or {})}
    return {
        code: {"model": Problem, "description": named.get(code, HTTPStatus(code).phrase)} for code in codes
    }


PROBLEM_RESPONSES: dict[int | str, Any] = problem_responses(*_DESCRIPTIONS)
"""The error statuses every route documents (the app includes every router with them)."""


def _is_problem(schema: object) -> bool:
    return isinstance(schema, dict) and schema.get("$ref") == "#/components/schemas/Problem"


def add_to_openapi(app: FastAPI) -> None:
    """Make ``app.openapi()`` file every :class:`Problem` answer under ``application/problem+json`` (FastAPI
    files a ``responses=`` model under the route's own media type)."""
    generate = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is not None:
            return app.openapi_schema
        document = generate()
        for path_item in document.get("paths", {}).values():
            for operation in path_item.values():
                for code, response in operation.get("responses", {}).items():
                    content = response.get("content", {})
                    if not code.isdigit() or int(code) < 400:
                        continue
                    for media_type, body in list(content.items()):
                        if media_type != PROBLEM_MEDIA_TYPE and _is_problem(body.get("schema")):
                            content[PROBLEM_MEDIA_TYPE] = content.pop(media_type)
        app.openapi_schema = document
        return document

    app.openapi = openapi  # type: ignore[method-assign]
