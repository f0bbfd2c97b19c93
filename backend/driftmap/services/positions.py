"""Vehicle positions: history by time range, the latest of every vehicle, and updates since a sequence.

A position's ``seq`` is its row id: it only grows, so a client that saw ``seq`` N resumes with every
position whose ``seq`` is above N.
"""

from __future__ import annotations

import gc
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import Select, func, select
from sqlalchemy.orm import Session

from driftmap.store.access_models import Vehicle, VehiclePosition
from driftmap.store.models import MapVersion, utc_now


def as_utc(moment: datetime) -> datetime:
    """``moment`` as aware UTC (SQLite returns naive datetimes that were stored as UTC)."""
    return moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(UTC)


@dataclass(frozen=True)
class PositionView:
    """One position of one vehicle, as the API shows it (see :class:`~driftmap.live.localise.FrameOutcome`)."""

    seq: int
    vehicle_id: int
    vehicle: str
    site_id: int
    t: float
    node: int
    x: float
    y: float
    yaw: float | None
    confidence: float
    matched: bool
    lost: bool
    map_version: int | None
    received_at: datetime
    speed_mps: float | None = None
    moving: bool | None = None
    odometry: bool = False
    obscured: bool | None = None
    """The camera looked obscured at this frame (None: not judged)."""
    obscured_reason: str | None = None
    salient: float | None = None
    sharpness: float | None = None
    speckle: float | None = None
    flat_area: float | None = None


@dataclass(frozen=True)
class VehicleLatest:
    """A vehicle with its last known position (None before its first) and whether that is stale."""

    vehicle_id: int
    vehicle: str
    site_id: int
    stale: bool
    position: PositionView | None


_COLUMNS = (
    VehiclePosition.id,
    VehiclePosition.vehicle_id,
    Vehicle.name,
    Vehicle.site_id,
    VehiclePosition.t_s,
    VehiclePosition.node,
    VehiclePosition.x_m,
    VehiclePosition.y_m,
    VehiclePosition.yaw_rad,
    VehiclePosition.confidence,
    VehiclePosition.matched,
    VehiclePosition.lost,
    MapVersion.version,
    VehiclePosition.received_at,
    VehiclePosition.speed_mps,
    VehiclePosition.moving,
    VehiclePosition.odometry,
    VehiclePosition.obscured,
    VehiclePosition.obscured_reason,
    VehiclePosition.salient,
    VehiclePosition.sharpness,
    VehiclePosition.speckle,
    VehiclePosition.flat_area,
)
"""The columns :func:`_view` unpacks, in its order."""


def _query() -> Select[*tuple[Any, ...]]:
    """Plain columns, not ORM objects: an hour of one vehicle is 36,000 rows, and building (and tracking) an
    object per row costs several times what the row itself does."""
    return (
        select(*_COLUMNS)
        .select_from(VehiclePosition)
        .join(Vehicle, VehiclePosition.vehicle_id == Vehicle.id)
        .outerjoin(MapVersion, VehiclePosition.map_version_id == MapVersion.id)
    )


def _view(row: Sequence[Any]) -> PositionView:
    (seq, vehicle_id, vehicle, site_id, t, node, x, y, yaw, confidence, matched, lost, version, received_at,
     speed_mps, moving, odometry, obscured, reason, salient, sharpness, speckle, flat_area) = row  # fmt: skip
    return PositionView(
        seq=seq, vehicle_id=vehicle_id, vehicle=vehicle, site_id=site_id, t=t, node=node, x=x, y=y, yaw=yaw,
        confidence=confidence, matched=matched, lost=lost, map_version=version, received_at=as_utc(received_at),
        speed_mps=speed_mps, moving=moving, odometry=bool(odometry), obscured=obscured, obscured_reason=reason,
        salient=salient, sharpness=sharpness, speckle=speckle, flat_area=flat_area,
    )  # fmt: skip


@contextmanager
def _collector_paused() -> Iterator[None]:
    """Python's cyclic garbage collector paused while a long result becomes views (an hour of one vehicle is
    36,000 rows): rows and views hold no reference cycles, yet the collections their allocations trigger cost
    about half as much again as building them. Another thread that pauses it too may see it re-enabled early,
    never left off."""
    paused = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if paused:
            gc.enable()


def history(
    session: Session,
    vehicle_id: int,
    start_s: float | None = None,
    end_s: float | None = None,
    limit: int = 10000,
) -> list[PositionView]:
    """A vehicle's positions with ``start_s <= t <= end_s`` (vehicle clock, seconds), in ``t`` order."""
    query = _query().where(VehiclePosition.vehicle_id == vehicle_id)
    if start_s is not None:
        query = query.where(VehiclePosition.t_s >= start_s)
    if end_s is not None:
        query = query.where(VehiclePosition.t_s <= end_s)
    with _collector_paused():
        rows = session.execute(query.order_by(VehiclePosition.t_s).limit(limit)).all()
        return [_view(row) for row in rows]


def since(session: Session, seq: int, limit: int = 10000) -> list[PositionView]:
    """Positions of every vehicle with a sequence number above ``seq``, oldest first."""
    with _collector_paused():
        rows = session.execute(
            _query().where(VehiclePosition.id > seq).order_by(VehiclePosition.id).limit(limit)
        ).all()
        return [_view(row) for row in rows]


def last_seq(session: Session) -> int:
    """The highest sequence number stored (0 before any position)."""
    return session.scalar(select(func.max(VehiclePosition.id))) or 0


def is_stale(position: PositionView | None, stale_after_s: float, now: datetime | None = None) -> bool:
    """Whether a vehicle whose last position is ``position`` counts as stale now."""
    if position is None:
        return True
    return ((now or utc_now()) - position.received_at).total_seconds() > stale_after_s


def latest(session: Session, stale_after_s: float, site_id: int | None = None) -> list[VehicleLatest]:
    """Every vehicle (of one site when given) with its last known position and stale flag."""
    newest = (
        select(VehiclePosition.vehicle_id, func.max(VehiclePosition.id).label("id"))
        .group_by(VehiclePosition.vehicle_id)
        .subquery()
    )
    positions = {
        view.vehicle_id: view
        for view in (
            _view(row) for row in session.execute(_query().join(newest, VehiclePosition.id == newest.c.id))
        )
    }
    vehicles = select(Vehicle).order_by(Vehicle.id)
    if site_id is not None:
        vehicles = vehicles.where(Vehicle.site_id == site_id)
    now = utc_now()
    out = []
    for vehicle in session.scalars(vehicles):
        position = positions.get(vehicle.id)
        out.append(
            VehicleLatest(
                vehicle.id, vehicle.name, vehicle.site_id, is_stale(position, stale_after_s, now), position
            )
        )
    return out
