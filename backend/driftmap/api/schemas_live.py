"""The messages of the ``/api/live`` WebSocket (see :mod:`driftmap.api.live`), one model per kind.

The server sends each as ``model.model_dump(mode="json")``. FastAPI leaves WebSocket routes out of the OpenAPI
document, so :func:`add_to_openapi` puts :class:`LiveMessage` and the models it names into the document's
components; the browser's types (``frontend/src/api/schema.d.ts``) are generated from there.
"""

from __future__ import annotations

from dataclasses import asdict
from datetime import datetime
from typing import Annotated, Any, Literal

from fastapi import FastAPI
from fastapi.encoders import jsonable_encoder
from fastapi.openapi.models import Schema
from pydantic import BaseModel, Field, RootModel
from pydantic.json_schema import models_json_schema

from driftmap.api.schemas_access import PositionRead, VehicleLatestRead
from driftmap.api.schemas_events import EventChangeKind, EventRead
from driftmap.live.hub import Message
from driftmap.services.events import EventChange
from driftmap.services.positions import PositionView


class LiveSnapshot(BaseModel):
    """The first message: every vehicle with its last position (the rows of ``GET /api/positions/latest``)."""

    type: Literal["snapshot"] = "snapshot"
    seq: int
    """The highest position ``seq`` stored when the snapshot was taken (0 before any)."""
    stale_after_s: float
    """A vehicle without a position for this long, seconds, is stale."""
    vehicles: list[VehicleLatestRead]
    events: list[EventRead] = Field(default_factory=list)
    """The events nobody acknowledged yet, newest first (at most 500)."""


class LivePosition(PositionRead):
    """A vehicle's new position."""

    type: Literal["position"] = "position"


class LiveStale(BaseModel):
    """A vehicle stopped reporting for ``stale_after_s``."""

    type: Literal["stale"] = "stale"
    vehicle_id: int
    received_at: datetime
    """When its last position arrived."""


class LiveEvent(EventRead):
    """An event opened, closed (its condition ended) or acknowledged: the event as it now is."""

    type: Literal["event"] = "event"
    change: EventChangeKind


class LiveMessage(
    RootModel[Annotated[LiveSnapshot | LivePosition | LiveStale | LiveEvent, Field(discriminator="type")]]
):
    """One message of the ``/api/live`` WebSocket, told apart by ``type``."""


def position_message(view: PositionView) -> Message:
    """The ``/api/live`` message of one position (a :class:`LivePosition`)."""
    return LivePosition.model_validate(view).model_dump(mode="json")


def event_message(change: EventChange) -> Message:
    """The ``/api/live`` message of an event's change (a :class:`LiveEvent`)."""
    return LiveEvent.model_validate({**asdict(change.event), "change": change.change}).model_dump(mode="json")


def add_to_openapi(app: FastAPI) -> None:
    """Make ``app.openapi()`` include :class:`LiveMessage` and its parts in ``components.schemas``.

    A model the routes already put there (``PositionRead``) must come out the same, or this raises
    RuntimeError.
    """
    generate = app.openapi

    def openapi() -> dict[str, Any]:
        if app.openapi_schema is not None:
            return app.openapi_schema
        document = generate()
        _, extra = models_json_schema(
            [(LiveMessage, "serialization")], ref_template="#/components/schemas/{model}"
        )
        schemas = document.setdefault("components", {}).setdefault("schemas", {})
        for name, raw in extra["$defs"].items():
            # encoded as FastAPI encodes its own components (no ``default: null``), so shared ones compare equal
            schema = jsonable_encoder(Schema(**raw), by_alias=True, exclude_none=True)
            if schemas.setdefault(name, schema) != schema:
                raise RuntimeError(
                    f"OpenAPI component {name} differs between the routes and the live messages"
                )
        app.openapi_schema = document
        return document

    app.openapi = openapi  # type: ignore[method-assign]
