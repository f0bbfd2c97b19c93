"""The control room's event log: list, export as CSV, acknowledge (every logged-in user).

The live path opens and ends events (:mod:`driftmap.live.event_watch`); these routes read them and record
acknowledgements. An acknowledgement is pushed to every ``/api/live`` watcher, so each control-room screen
sees it at once. Times in queries are ISO 8601; one without a zone is UTC.
"""

from __future__ import annotations

import asyncio
from datetime import datetime
from typing import Annotated

from fastapi import APIRouter, Depends, Query, Request
from fastapi.responses import Response

from driftmap.api.deps import VIEWER, Principal, SessionDep, ViewerDep
from driftmap.api.groundings import attachment
from driftmap.api.input_types import Count, Id
from driftmap.api.schemas_data import Page
from driftmap.api.schemas_events import EventRead
from driftmap.errors import BadInputError
from driftmap.live.ingest import LiveService
from driftmap.services import events as event_service
from driftmap.services.events import EventChange, EventFilter, EventView
from driftmap.services.positions import as_utc
from driftmap.store.event_models import EventKind
from driftmap.store.models import utc_now
from driftmap.store.storage import Storage

router = APIRouter(tags=["events"])


def event_filter(
    site: Annotated[Id | None, Query(description="Only events of this site (its id).")] = None,
    vehicle: Annotated[Id | None, Query(description="Only events of this vehicle (its id).")] = None,
    kind: Annotated[EventKind | None, Query(description="Only events of this kind.")] = None,
    open_: Annotated[
        bool | None, Query(alias="open", description="true: only events still on; false: only ended ones.")
    ] = None,
    unacknowledged: Annotated[
        bool | None,
        Query(description="true: only events nobody acknowledged; false: only acknowledged ones."),
    ] = None,
    since: Annotated[
        datetime | None, Query(description="Only events still on at or after this time (ISO 8601).")
    ] = None,
    until: Annotated[
        datetime | None, Query(description="Only events started at or before this time.")
    ] = None,
) -> EventFilter:
    """The filter of an events query; ``until`` before ``since`` is a 422 naming ``until``."""
    since, until = since and as_utc(since), until and as_utc(until)
    if since is not None and until is not None and until < since:
        raise BadInputError(f"{until.isoformat()} is before since ({since.isoformat()})", field="until")
    return EventFilter(site, vehicle, kind, open_, unacknowledged, since, until)


EventFilterDep = Annotated[EventFilter, Depends(event_filter)]


@router.get("/events", dependencies=[Depends(VIEWER)])
def list_events(
    session: SessionDep,
    filters: EventFilterDep,
    offset: Annotated[Count, Query()] = 0,
    limit: Annotated[int, Query(ge=1, le=500)] = 100,
) -> Page[EventRead]:
    """The events that pass the filters, newest first, a page at a time."""
    views, total = event_service.list_events(session, filters, offset, limit)
    return Page[EventRead](
        items=[EventRead.model_validate(v) for v in views], total=total, offset=offset, limit=limit
    )


@router.get(
    "/events.csv",
    dependencies=[Depends(VIEWER)],
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}, "description": "The events, oldest first."}},
)
def export_events(session: SessionDep, filters: EventFilterDep) -> Response:
    """The events that pass the filters as a CSV file (docs/formats.md, Events), oldest first."""
    text = event_service.export_events(session, filters)
    return Response(
        text.encode("utf-8"), media_type="text/csv", headers={"Content-Disposition": attachment("events.csv")}
    )


def _acknowledge(storage: Storage, event_id: int, user: Principal) -> tuple[EventView, bool]:
    with storage.db.session() as session:
        return event_service.acknowledge(session, event_id, user.id, user.name, utc_now())


@router.post("/events/{event_id}/ack")
async def acknowledge_event(event_id: Id, request: Request, user: ViewerDep) -> EventRead:
    """Acknowledge an event as the calling user (again: the first acknowledgement stays); 404 when unknown."""
    view, changed = await asyncio.to_thread(_acknowledge, request.app.state.storage, event_id, user)
    if changed:
        live: LiveService = request.app.state.live
        await live.publish_event(EventChange("acknowledged", view))
    return EventRead.model_validate(view)
