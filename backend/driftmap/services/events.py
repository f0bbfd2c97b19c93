"""The control room's event log: opening and ending events, acknowledging, listing and exporting them.

Rows are :class:`~driftmap.store.event_models.VehicleEvent`. The live path decides when a condition begins
or ends (:mod:`driftmap.live.events`) and calls :func:`open_event` and :func:`end_events` in the frame's
transaction; :func:`silent_vehicles` finds the vehicles that stopped reporting. Every change comes back as an
:class:`EventChange` for the live push. Times are aware UTC; callers commit.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime
from typing import Literal

from sqlalchemy import Select, and_, exists, func, or_, select, update
from sqlalchemy.exc import IntegrityError
from sqlalchemy.orm import Session

from driftmap.errors import NotFoundError
from driftmap.formats.event_exports import EventRow, events_text
from driftmap.services.positions import as_utc
from driftmap.store.access_models import Vehicle, VehicleLiveState, VehiclePosition
from driftmap.store.event_models import VehicleEvent

Change = Literal["opened", "closed", "acknowledged"]


@dataclass(frozen=True)
class EventView:
    """One event as the API shows it; positions survey-frame metres, times aware UTC."""

    id: int
    site_id: int
    vehicle_id: int
    vehicle: str
    kind: str
    detail: str | None
    started_at: datetime
    ended_at: datetime | None
    x: float | None
    y: float | None
    acknowledged_by: str | None
    acknowledged_at: datetime | None
    updated_at: datetime


@dataclass(frozen=True)
class EventChange:
    """What happened to an event: ``opened``, ``closed`` (its condition ended) or ``acknowledged``."""

    change: Change
    event: EventView


@dataclass(frozen=True)
class EventFilter:
    """Which events a list or export holds; None leaves a criterion out."""

    site_id: int | None = None
    vehicle_id: int | None = None
    kind: str | None = None
    open: bool | None = None
    """True: only events still on; False: only ended ones."""
    unacknowledged: bool | None = None
    """True: only events nobody acknowledged; False: only acknowledged ones."""
    since: datetime | None = None
    """Only events still on at or after this moment (ended at or after it, or not ended)."""
    until: datetime | None = None
    """Only events started at or before this moment."""


def _optional_utc(moment: datetime | None) -> datetime | None:
    return None if moment is None else as_utc(moment)


def _view(row: VehicleEvent, vehicle: str) -> EventView:
    return EventView(
        id=row.id,
        site_id=row.site_id,
        vehicle_id=row.vehicle_id,
        vehicle=vehicle,
        kind=row.kind,
        detail=row.detail,
        started_at=as_utc(row.started_at),
        ended_at=_optional_utc(row.ended_at),
        x=row.x_m,
        y=row.y_m,
        acknowledged_by=row.acknowledged_by,
        acknowledged_at=_optional_utc(row.acknowledged_at),
        updated_at=as_utc(row.updated_at),
    )


def change_of(view: EventView) -> Change:
    """The latest change an event went through, read from its state."""
    if view.acknowledged_at is not None:
        return "acknowledged"
    return "opened" if view.ended_at is None else "closed"


def open_kinds(session: Session, vehicle_id: int) -> frozenset[str]:
    """The kinds of the vehicle's open events."""
    query = select(VehicleEvent.kind).where(
        VehicleEvent.vehicle_id == vehicle_id, VehicleEvent.ended_at.is_(None)
    )
    return frozenset(session.scalars(query))


def open_event(
    session: Session,
    vehicle: Vehicle,
    kind: str,
    at: datetime,
    x: float | None,
    y: float | None,
    detail: str | None = None,
) -> EventChange:
    """Open an event of ``vehicle`` started ``at`` (UTC) at its last known position ``x, y`` (metres).

    Raises:
        IntegrityError: the vehicle has an open event of this kind (from the flush).
    """
    row = VehicleEvent(
        site_id=vehicle.site_id, vehicle_id=vehicle.id, kind=kind, detail=detail, started_at=at, x_m=x, y_m=y
    )
    row.updated_at = at
    session.add(row)
    session.flush()
    return EventChange("opened", _view(row, vehicle.name))


def open_event_once(
    session: Session, vehicle: Vehicle, kind: str, at: datetime, x: float | None, y: float | None
) -> EventChange | None:
    """:func:`open_event` in a savepoint; None when another process opened that kind meanwhile."""
    try:
        with session.begin_nested():
            return open_event(session, vehicle, kind, at, x, y)
    except IntegrityError:
        return None


def end_events(session: Session, vehicle: Vehicle, kinds: Iterable[str], at: datetime) -> list[EventChange]:
    """End the vehicle's open events of ``kinds`` at ``at`` (UTC); their changes, in ``kinds`` order."""
    wanted = list(kinds)
    if not wanted:
        return []
    rows = session.scalars(
        select(VehicleEvent).where(
            VehicleEvent.vehicle_id == vehicle.id,
            VehicleEvent.kind.in_(wanted),
            VehicleEvent.ended_at.is_(None),
        )
    ).all()
    for row in rows:
        row.ended_at = at
        row.updated_at = at
    session.flush()
    rows = sorted(rows, key=lambda r: wanted.index(r.kind))
    return [EventChange("closed", _view(r, vehicle.name)) for r in rows]


@dataclass(frozen=True)
class SilentVehicle:
    """A vehicle whose last position arrived before a cutoff and that has no open ``stale`` event."""

    vehicle: Vehicle
    reported_at: datetime
    """When its last position arrived (UTC)."""
    x: float | None
    """Its last position, survey-frame metres (None when the history no longer holds it)."""
    y: float | None


def silent_vehicles(session: Session, cutoff: datetime) -> list[SilentVehicle]:
    """The vehicles last heard from before ``cutoff`` (UTC) without an open ``stale`` event."""
    stale_open = exists().where(
        VehicleEvent.vehicle_id == VehicleLiveState.vehicle_id,
        VehicleEvent.kind == "stale",
        VehicleEvent.ended_at.is_(None),
    )
    rows = session.execute(
        select(Vehicle, VehicleLiveState.reported_at)
        .join(VehicleLiveState, VehicleLiveState.vehicle_id == Vehicle.id)
        .where(VehicleLiveState.reported_at < as_utc(cutoff), ~stale_open)
        .order_by(Vehicle.id)
    ).all()
    out = []
    for vehicle, reported_at in rows:
        assert reported_at is not None  # (the query's condition)
        last = session.execute(
            select(VehiclePosition.x_m, VehiclePosition.y_m)
            .where(VehiclePosition.vehicle_id == vehicle.id)
            .order_by(VehiclePosition.t_s.desc())
            .limit(1)
        ).first()
        x, y = (None, None) if last is None else (last[0], last[1])
        out.append(SilentVehicle(vehicle, as_utc(reported_at), x, y))
    return out


def record_known_start(
    session: Session,
    vehicle: Vehicle,
    x: float,
    y: float,
    radius_m: float,
    user_id: int,
    user: str,
    at: datetime,
) -> EventChange:
    """Log a known start set by ``user`` at ``x, y`` (metres): an instant event they acknowledge by setting it."""
    row = VehicleEvent(
        site_id=vehicle.site_id,
        vehicle_id=vehicle.id,
        kind="start_known",
        detail=f"radius {radius_m:g} m",
        started_at=at,
        ended_at=at,
        x_m=x,
        y_m=y,
        acknowledged_by_id=user_id,
        acknowledged_by=user,
        acknowledged_at=at,
        updated_at=at,
    )
    session.add(row)
    session.flush()
    return EventChange("opened", _view(row, vehicle.name))


def acknowledge(
    session: Session, event_id: int, user_id: int, user: str, at: datetime
) -> tuple[EventView, bool]:
    """Acknowledge an event as ``user`` at ``at`` (UTC); the event and whether this call acknowledged it.

    An event acknowledged before keeps its first acknowledgement (the call changes nothing).

    Raises:
        NotFoundError: no event ``event_id``.
    """
    changed = session.execute(
        update(VehicleEvent)
        .where(VehicleEvent.id == event_id, VehicleEvent.acknowledged_at.is_(None))
        .values(acknowledged_by_id=user_id, acknowledged_by=user, acknowledged_at=at, updated_at=at)
    ).rowcount  # type: ignore[attr-defined]
    found = session.execute(
        _query().where(VehicleEvent.id == event_id).execution_options(populate_existing=True)
    )
    row = found.first()
    if row is None:
        raise NotFoundError(f"no event with id {event_id}")
    return _view(row[0], row[1]), bool(changed)


def _query() -> Select[VehicleEvent, str]:
    return select(VehicleEvent, Vehicle.name).join(Vehicle, VehicleEvent.vehicle_id == Vehicle.id)


def _filtered(query: Select[VehicleEvent, str], f: EventFilter) -> Select[VehicleEvent, str]:
    conditions = []
    if f.site_id is not None:
        conditions.append(VehicleEvent.site_id == f.site_id)
    if f.vehicle_id is not None:
        conditions.append(VehicleEvent.vehicle_id == f.vehicle_id)
    if f.kind is not None:
        conditions.append(VehicleEvent.kind == f.kind)
    if f.open is not None:
        conditions.append(VehicleEvent.ended_at.is_(None) if f.open else VehicleEvent.ended_at.is_not(None))
    if f.unacknowledged is not None:
        column = VehicleEvent.acknowledged_at
        conditions.append(column.is_(None) if f.unacknowledged else column.is_not(None))
    if f.since is not None:
        since = as_utc(f.since)
        conditions.append(or_(VehicleEvent.ended_at.is_(None), VehicleEvent.ended_at >= since))
    if f.until is not None:
        conditions.append(VehicleEvent.started_at <= as_utc(f.until))
    return query.where(and_(*conditions)) if conditions else query


def list_events(
    session: Session, filters: EventFilter, offset: int, limit: int
) -> tuple[list[EventView], int]:
    """A page of the events that pass ``filters``, newest first, and how many pass in all."""
    query = _filtered(_query(), filters)
    total = session.scalar(select(func.count()).select_from(query.subquery())) or 0
    rows = session.execute(
        query.order_by(VehicleEvent.started_at.desc(), VehicleEvent.id.desc()).offset(offset).limit(limit)
    ).all()
    return [_view(e, name) for e, name in rows], int(total)


def changed_since(session: Session, moment: datetime, limit: int) -> list[EventChange]:
    """Events that changed at or after ``moment`` (UTC), oldest change first (at most ``limit``)."""
    rows = session.execute(
        _query()
        .where(VehicleEvent.updated_at >= as_utc(moment))
        .order_by(VehicleEvent.updated_at)
        .limit(limit)
    ).all()
    views = [_view(e, name) for e, name in rows]
    return [EventChange(change_of(v), v) for v in views]


def export_events(session: Session, filters: EventFilter) -> str:
    """The CSV text (``docs/formats.md``, Events) of every event that passes ``filters``, oldest first."""
    rows = session.execute(
        _filtered(_query(), filters).order_by(VehicleEvent.started_at, VehicleEvent.id)
    ).all()
    return events_text(_row(_view(e, name)) for e, name in rows)


def _row(view: EventView) -> EventRow:
    return EventRow(
        id=view.id,
        site_id=view.site_id,
        vehicle=view.vehicle,
        kind=view.kind,
        detail=view.detail,
        started_at=view.started_at,
        ended_at=view.ended_at,
        x_m=view.x,
        y_m=view.y,
        acknowledged_by=view.acknowledged_by,
        acknowledged_at=view.acknowledged_at,
    )
