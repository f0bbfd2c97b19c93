"""Who opened a WebSocket: the handshake's credentials, or a first ``auth`` message.

A client that can set headers (a vehicle, a script) sends ``Authorization: Bearer <token>`` with the
handshake; a browser on the same origin sends the login cookie. A client that can do neither (a browser
whose cookie was not kept, e.g. on plain HTTP, where the ``Secure`` cookie is dropped) opens the socket
without credentials and sends, as its first message, the text

    {"type": "auth", "token": "<token>"}

within :data:`AUTH_MESSAGE_TIMEOUT_S`. Tokens in the URL (``?token=``) are refused: URLs end up in access
logs and browser histories.

A long-lived socket checks its token again with :func:`still_valid` (every :data:`TOKEN_RECHECK_S`), so a
revoked token does not keep a socket open.
"""

from __future__ import annotations

import asyncio
import json

from fastapi import WebSocket, WebSocketDisconnect

from driftmap.api.deps import Principal, cached_principal, token_of

AUTH_MESSAGE_TIMEOUT_S = 10.0
"""How long a WebSocket without handshake credentials has to send its ``auth`` message, seconds."""
TOKEN_RECHECK_S = 2.0
"""How often a long-lived socket checks that its token is still valid, seconds."""
MAX_AUTH_MESSAGE_CHARS = 4096
"""Longest accepted ``auth`` message (a token is a few hundred characters)."""


class WebSocketAuthError(Exception):
    """The credentials of a WebSocket are missing or malformed; the message (a WebSocket close reason, at
    most 100 characters) says what to send."""


async def _first_message_token(websocket: WebSocket, timeout_s: float) -> str:
    try:
        message = await asyncio.wait_for(websocket.receive(), timeout_s)
    except TimeoutError:
        raise WebSocketAuthError(f"no auth message within {timeout_s:g} s") from None
    if message["type"] == "websocket.disconnect":
        raise WebSocketDisconnect(int(message.get("code", 1000)))
    text = message.get("text")
    if not isinstance(text, str) or len(text) > MAX_AUTH_MESSAGE_CHARS:
        raise WebSocketAuthError('the first message must be the text {"type": "auth", "token": "..."}')
    try:
        body = json.loads(text)
    except ValueError:
        body = None
    token = body.get("token") if isinstance(body, dict) and body.get("type") == "auth" else None
    if not isinstance(token, str) or not token:
        raise WebSocketAuthError('the first message must be the text {"type": "auth", "token": "..."}')
    return token


async def websocket_principal(
    websocket: WebSocket, *, timeout_s: float = AUTH_MESSAGE_TIMEOUT_S
) -> Principal | None:
    """Who opened the (accepted) ``websocket``: its header or cookie token, else its first-message token.

    Returns None for a token that is not valid (revoked, expired, unknown). Raises
    :class:`WebSocketAuthError` when no token came, or it came in the URL.
    """
    token = token_of(websocket)
    if token is None:
        if "token" in websocket.query_params:
            raise WebSocketAuthError(
                "tokens in URLs are refused: send a bearer header or a first auth message"
            )
        token = await _first_message_token(websocket, timeout_s)
    websocket.state.token = token
    return await cached_principal(websocket, token)


async def still_valid(websocket: WebSocket) -> bool:
    """Whether the token ``websocket`` authenticated with is still valid (not revoked, expired or disabled)."""
    token = getattr(websocket.state, "token", None)
    return token is not None and await cached_principal(websocket, token) is not None
