"""Live localisation: vehicles post frames (HTTP or a WebSocket stream), watchers follow ``/api/live``.

The routes hand frames to the process's :class:`~driftmap.live.ingest.LiveService` (``app.state.live``).

``POST /api/vehicles/{id}/frames?t=SECONDS`` takes the JPEG or PNG bytes as the body (``Content-Type:
image/jpeg`` or ``image/png``) and answers with a :class:`~driftmap.api.schemas_access.FrameEstimate`.

``GET /api/vehicles/{id}/frames/latest`` (any logged-in user) returns the vehicle's last localised frame as it
was posted (``X-Frame-T`` carries its ``t``), kept in the server process's memory, or in Redis when
``DRIFTMAP_REDIS_URL`` is set so that every API process serves it.

``/api/vehicles/{id}/stream`` (WebSocket, the vehicle's token as bearer header or in a first ``auth``
message, :mod:`driftmap.api.ws_auth`): each binary
message is one frame: ``t`` as an 8-byte big-endian IEEE float64 (seconds), then the JPEG/PNG bytes. The
server answers each frame with one JSON text message, a FrameEstimate, or ``{"status": "error", "t",
"code", "detail", "field"}`` for a frame it cannot use (the stream stays open).

``/api/live`` (WebSocket, any logged-in user: bearer header, cookie, or a first ``auth`` message; the messages are
the models of :mod:`driftmap.api.schemas_live`, in the OpenAPI components as ``LiveMessage``): first
``{"type": "snapshot", "seq", "stale_after_s", "vehicles": [...]}``, every vehicle with its last position;
with ``?since=SEQ`` then every ``{"type": "position", ...}`` after SEQ up to the snapshot (to resume after a
reconnect); then live ``position`` messages, ``{"type": "stale", "vehicle_id", "received_at"}`` when a
vehicle stops reporting for ``stale_after_s``, and ``{"type": "event", "change", ...}`` when an event of the
log (:mod:`driftmap.api.events`) opens, closes or is acknowledged, by whoever and on whichever API process.
The snapshot carries the events nobody acknowledged yet (``events``); a watcher that fell behind gets the
events changed meanwhile again with the positions it missed. A watcher gets each position once and each
vehicle's positions in order; positions of different vehicles may arrive out of ``seq`` order (they are
localised by different processes), so a client resuming with ``?since=`` should pass the smallest of its
vehicles' last ``seq``.
"""

from __future__ import annotations

import asyncio
import contextlib
import struct
import time
from datetime import datetime, timedelta
from typing import Annotated, Any

from fastapi import APIRouter, Depends, Query, Request, Response, WebSocket, WebSocketDisconnect
from starlette.requests import ClientDisconnect

from driftmap.api.deps import VIEWER, WS_CLOSE_FORBIDDEN, WS_CLOSE_UNAUTHORIZED, Principal, VehicleDep
from driftmap.api.error_handlers import error_body, status_of
from driftmap.api.input_types import Count, Id, Seconds
from driftmap.api.schemas_access import FrameEstimate, VehicleLatestRead
from driftmap.api.schemas_events import EventRead
from driftmap.api.schemas_live import LiveSnapshot, LiveStale, event_message, position_message
from driftmap.api.ws_auth import TOKEN_RECHECK_S, WebSocketAuthError, still_valid, websocket_principal
from driftmap.errors import BadRequestError, DriftmapError, NotFoundError, PayloadTooLargeError
from driftmap.live.ingest import LiveService
from driftmap.services import events as event_service
from driftmap.services import positions as position_service
from driftmap.services import vehicles as vehicle_service
from driftmap.services.events import EventFilter
from driftmap.services.positions import as_utc
from driftmap.store.models import utc_now

router = APIRouter(tags=["live"])
IMAGE_TYPES = ("image/jpeg", "image/png")
_IMAGE_BODY = {"schema": {"type": "string", "format": "binary"}}
SNAPSHOT_EVENTS = 500  # unacknowledged events in a snapshot, newest first
RESYNC_MARGIN_S = 5.0  # a watcher that fell behind gets the events changed since then less this, seconds
RESYNC_EVENTS = 1000  # at most this many events resent to a watcher that fell behind


def _live(app_state: Any) -> LiveService:
    live: LiveService = app_state.live
    return live


async def _read_body(request: Request, limit: int) -> bytes:
    declared = request.headers.get("content-length")
    if declared is not None and declared.isdigit() and int(declared) > limit:
        raise PayloadTooLargeError(f"frame of {declared} bytes is over the {limit} byte limit", field="body")
    chunks, total = [], 0
    try:
        async for chunk in request.stream():
            total += len(chunk)
            if total > limit:
                raise PayloadTooLargeError(f"frame is over the {limit} byte limit", field="body")
            chunks.append(chunk)
    except ClientDisconnect:
        raise BadRequestError("the client went away before sending the whole frame", field="body") from None
    return b"".join(chunks)


@router.post(
    "/vehicles/{vehicle_id}/frames",
    openapi_extra={"requestBody": {"required": True, "content": dict.fromkeys(IMAGE_TYPES, _IMAGE_BODY)}},
)
async def post_frame(
    vehicle: VehicleDep,
    request: Request,
    t: Annotated[
        Seconds, Query(description="The frame's time on the vehicle's clock, seconds; must increase.")
    ],
) -> FrameEstimate:
    """Localise one camera frame of this vehicle (its own token only) on its site's latest map."""
    content_type = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if content_type not in IMAGE_TYPES:
        raise BadRequestError(
            f"send the frame as the body with Content-Type image/jpeg or image/png, not {content_type or 'none'!r}",
            field="content-type",
        )
    data = await _read_body(request, request.app.state.settings.max_frame_bytes)
    if not data:
        raise BadRequestError("the request has no body: send the JPEG or PNG bytes", field="body")
    outcome = await _live(request.app.state).submit(vehicle.id, vehicle.name, vehicle.site_id or 0, t, data)
    return FrameEstimate.model_validate(outcome)


@router.get(
    "/vehicles/{vehicle_id}/frames/latest",
    dependencies=[Depends(VIEWER)],
    response_class=Response,
    responses={
        200: {"content": dict.fromkeys(IMAGE_TYPES, _IMAGE_BODY), "description": "The frame's bytes."}
    },
)
async def latest_frame(vehicle_id: Id, request: Request) -> Response:
    """The vehicle's last localised frame (404 before its first; without Redis, 404 too when another server
    process localised it)."""
    await asyncio.to_thread(_check_vehicle, request, vehicle_id)
    found = await _live(request.app.state).latest_frame(vehicle_id)
    if found is None:
        raise NotFoundError(f"no frame of vehicle {vehicle_id} localised yet (or it expired)")
    t, data = found
    media_type = "image/png" if data.startswith(b"\x89PNG") else "image/jpeg"
    return Response(data, media_type=media_type, headers={"X-Frame-T": repr(t), "Cache-Control": "no-store"})


def _check_vehicle(request: Request, vehicle_id: int) -> None:
    with request.app.state.storage.db.session() as session:
        vehicle_service.get_vehicle(session, vehicle_id)


async def _authorise(websocket: WebSocket, vehicle_id: int | None) -> Principal | None:
    """Accept ``websocket``; close it again unless its credentials fit (a user; or vehicle ``vehicle_id``)."""
    await websocket.accept()
    try:
        principal = await websocket_principal(websocket)
    except WebSocketAuthError as exc:
        await websocket.close(WS_CLOSE_UNAUTHORIZED, f"not authenticated: {exc}"[:120])
        return None
    except WebSocketDisconnect:
        return None
    if principal is None:
        await websocket.close(WS_CLOSE_UNAUTHORIZED, "not authenticated: the token is not valid")
        return None
    allowed = (
        principal.kind == "user"
        if vehicle_id is None
        else principal.kind == "vehicle" and principal.id == vehicle_id
    )
    if not allowed:
        await websocket.close(WS_CLOSE_FORBIDDEN, "these credentials may not open this stream")
        return None
    return principal


@router.websocket("/vehicles/{vehicle_id}/stream")
async def vehicle_stream(websocket: WebSocket, vehicle_id: int) -> None:
    """A vehicle's continuous frame stream (see the module docstring for the framing)."""
    principal = await _authorise(websocket, vehicle_id)
    if principal is None:
        return
    live = _live(websocket.app.state)
    limit = websocket.app.state.settings.max_frame_bytes
    send_lock = asyncio.Lock()
    pending: set[asyncio.Task[None]] = set()

    async def send(message: dict[str, Any]) -> None:
        async with send_lock:
            with contextlib.suppress(WebSocketDisconnect, RuntimeError):
                await websocket.send_json(message)

    async def answer(t: float, submitted: asyncio.Task[Any]) -> None:
        try:
            outcome = await submitted
            await send(FrameEstimate.model_validate(outcome).model_dump(mode="json"))
        except DriftmapError as exc:
            await send({"status": "error", "t": t, "code": status_of(exc), **error_body(exc)})

    checked_at = time.monotonic()
    try:
        while True:
            message = await websocket.receive()
            if message["type"] == "websocket.disconnect":
                break
            if time.monotonic() - checked_at > TOKEN_RECHECK_S:  # a rotated or deleted vehicle's token
                checked_at = time.monotonic()
                if not await still_valid(websocket):
                    await websocket.close(WS_CLOSE_UNAUTHORIZED, "the token was revoked or expired")
                    break
            data = message.get("bytes")
            t = float("nan")
            try:
                if data is None or len(data) < 9:
                    raise BadRequestError(
                        "send binary messages: t as 8-byte big-endian float64, then the image",
                        field="message",
                    )
                if len(data) - 8 > limit:
                    raise PayloadTooLargeError(f"frame is over the {limit} byte limit", field="message")
                (t,) = struct.unpack(">d", data[:8])
            except DriftmapError as exc:
                await send({"status": "error", "t": t, "code": status_of(exc), **error_body(exc)})
                continue
            submitted = asyncio.create_task(
                live.submit(principal.id, principal.name, principal.site_id or 0, t, data[8:])
            )
            task = asyncio.create_task(answer(t, submitted))
            pending.add(task)
            task.add_done_callback(pending.discard)
    finally:
        if pending:
            await asyncio.gather(*pending, return_exceptions=True)


def _snapshot(websocket: WebSocket) -> LiveSnapshot:
    storage = websocket.app.state.storage
    stale_after_s = websocket.app.state.settings.stale_after_s
    with storage.db.session() as session:
        seq = position_service.last_seq(session)
        vehicles = position_service.latest(session, stale_after_s)
        events, _total = event_service.list_events(
            session, EventFilter(unacknowledged=True), 0, SNAPSHOT_EVENTS
        )
    rows = [VehicleLatestRead.model_validate(v) for v in vehicles]
    unacknowledged = [EventRead.model_validate(e) for e in events]
    return LiveSnapshot(seq=seq, stale_after_s=stale_after_s, vehicles=rows, events=unacknowledged)


def _since(websocket: WebSocket, seq: int, upto: int | None = None) -> list[dict[str, Any]]:
    with websocket.app.state.storage.db.session() as session:
        views = position_service.since(session, seq)
    return [position_message(v) for v in views if upto is None or v.seq <= upto]


def _events_since(websocket: WebSocket, moment: datetime) -> list[dict[str, Any]]:
    """The event messages of the events changed since ``moment`` less ``RESYNC_MARGIN_S`` (other processes'
    clocks may lag a little)."""
    since = moment - timedelta(seconds=RESYNC_MARGIN_S)
    with websocket.app.state.storage.db.session() as session:
        changes = event_service.changed_since(session, since, RESYNC_EVENTS)
    return [event_message(c) for c in changes]


@router.websocket("/live")
async def live_updates(websocket: WebSocket, since: Count | None = None) -> None:
    """Positions of every vehicle as they arrive: a snapshot, then updates (see the module docstring)."""
    if await _authorise(websocket, None) is None:
        return
    live = _live(websocket.app.state)
    stale_after_s = float(websocket.app.state.settings.stale_after_s)
    subscription = live.hub.subscribe()
    synced_at = utc_now()  # every event change from here on is queued (or the watcher overflows)
    receiver = asyncio.create_task(_until_disconnect(websocket))
    try:
        snapshot = await asyncio.to_thread(_snapshot, websocket)
        floor = snapshot.seq
        await websocket.send_json(snapshot.model_dump(mode="json"))
        heard: dict[int, datetime] = {
            row.vehicle_id: row.position.received_at for row in snapshot.vehicles if row.position is not None
        }
        stale = {row.vehicle_id for row in snapshot.vehicles if row.stale}
        if since is not None:
            for message in await asyncio.to_thread(_since, websocket, since, floor):
                await websocket.send_json(message)
        sent: dict[int, int] = {}  # seq of the last position sent, by vehicle (the floor before the first)
        backlog: list[dict[str, Any]] = []
        checked_at = time.monotonic()
        while not receiver.done():
            if time.monotonic() - checked_at > TOKEN_RECHECK_S:
                checked_at = time.monotonic()
                if not await still_valid(websocket):
                    await websocket.close(WS_CLOSE_UNAUTHORIZED, "the token was revoked or expired")
                    break
            if not subscription.overflowed:
                synced_at = utc_now()  # nothing was dropped up to here
            else:
                subscription.drain()
                active = [seq for vehicle_id, seq in sent.items() if vehicle_id not in stale]
                resync_from = min(active) if active else max(sent.values(), default=floor)
                backlog = await asyncio.to_thread(_since, websocket, resync_from)
                backlog += await asyncio.to_thread(_events_since, websocket, synced_at)
            if not backlog:
                with contextlib.suppress(TimeoutError):
                    backlog.append(await asyncio.wait_for(subscription.queue.get(), 1.0))
            for message in backlog:
                if message["type"] == "event":
                    await websocket.send_json(message)
                    continue
                if message["type"] != "position" or message["seq"] <= sent.get(message["vehicle_id"], floor):
                    continue
                await websocket.send_json(message)
                sent[message["vehicle_id"]] = message["seq"]
                heard[message["vehicle_id"]] = datetime.fromisoformat(message["received_at"])
                stale.discard(message["vehicle_id"])
            backlog = []
            now = utc_now()
            for vehicle_id, at in heard.items():
                if vehicle_id not in stale and (now - as_utc(at)).total_seconds() > stale_after_s:
                    stale.add(vehicle_id)
                    await websocket.send_json(
                        LiveStale(vehicle_id=vehicle_id, received_at=at).model_dump(mode="json")
                    )
    except (WebSocketDisconnect, RuntimeError):
        pass
    finally:
        live.hub.unsubscribe(subscription)
        receiver.cancel()


async def _until_disconnect(websocket: WebSocket) -> None:
    """Read (and ignore) what a watcher sends until it disconnects."""
    with contextlib.suppress(WebSocketDisconnect, RuntimeError):
        while (await websocket.receive())["type"] != "websocket.disconnect":
            pass
