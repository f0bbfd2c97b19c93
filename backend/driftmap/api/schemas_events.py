"""Response bodies of the control room's event log (``/api/events``) and its query parameters' types."""

from __future__ import annotations

from datetime import datetime
from typing import Literal

from pydantic import BaseModel, ConfigDict

from driftmap.store.event_models import EventKind

EventChangeKind = Literal["opened", "closed", "acknowledged"]


class EventRead(BaseModel):
    """One event of a vehicle: a condition from ``started_at`` to ``ended_at`` (null while it lasts)."""

    model_config = ConfigDict(from_attributes=True)

    id: int
    site_id: int
    vehicle_id: int
    vehicle: str
    """The vehicle's name."""
    kind: EventKind
    """``lost``, ``obscured``, ``low_confidence``, ``stale`` or ``start_known``."""
    detail: str | None
    """A few words on the condition: the obscured camera's reason, the known start's radius."""
    started_at: datetime
    """When the condition began (UTC)."""
    ended_at: datetime | None
    """When it ended ("found again", "camera clear", "back"); null while it lasts."""
    x: float | None
    """The vehicle's last known position when the event started, survey-frame metres east (null: none)."""
    y: float | None
    """... metres north."""
    acknowledged_by: str | None
    """Who acknowledged the event (a user name); null until someone does."""
    acknowledged_at: datetime | None
    updated_at: datetime
    """When the event last changed (opened, ended or acknowledged)."""
