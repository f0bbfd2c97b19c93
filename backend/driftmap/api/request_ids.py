"""Every HTTP request gets an id for the logs (:mod:`driftmap.logs`), echoed as ``X-Request-ID``."""

from __future__ import annotations

import uuid

from starlette.types import ASGIApp, Message, Receive, Scope, Send

from driftmap.logs import REQUEST_ID, sane_request_id

HEADER = b"x-request-id"


class RequestIds:
    """ASGI middleware: the client's ``X-Request-ID`` when sane, else a new one; set for the request's logs
    and added to the response."""

    def __init__(self, app: ASGIApp) -> None:
        self.app = app

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] not in ("http", "websocket"):
            await self.app(scope, receive, send)
            return
        given = dict(scope.get("headers") or []).get(HEADER)
        request_id = sane_request_id(given.decode("latin-1") if given else None) or uuid.uuid4().hex
        token = REQUEST_ID.set(request_id)

        async def sending(message: Message) -> None:
            if message["type"] == "http.response.start":
                message.setdefault("headers", [])
                message["headers"] = [*message["headers"], (HEADER, request_id.encode())]
            await send(message)

        try:
            await self.app(scope, receive, sending)
        finally:
            REQUEST_ID.reset(token)
