"""Vehicle positions: history by time range, the latest of every vehicle, and updates since a sequence.

A position's ``seq`` is its row id: it only grows, so a client that saw ``seq`` N resumes with every
position whose ``seq`` is above N.
"""

from __future__ import annotations

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


@dataclass(slots=True)
class PositionView:
    """One position of one vehicle, as the API shows it (see :class:`~driftmap.live.localise.FrameOutcome`).

    Slotted and not frozen: an hour of one vehicle is 36,000 of them, and a frozen dataclass sets each field
    through ``object.__setattr__`` (several times the cost of building the row).
    """

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
    func.coalesce(VehiclePosition.odometry, False),
    VehiclePosition.obscured,
    VehiclePosition.obscured_reason,
    VehiclePosition.salient,
    VehiclePosition.sharpness,
    VehiclePosition.speckle,
    VehiclePosition.flat_area,
)
"""The columns of a :class:`PositionView`, in its fields' order (``received_at`` is read back aware UTC)."""


def _query() -> Select[*tuple[Any, ...]]:
    """Plain columns, not ORM objects: an hour of one vehicle is 36,000 rows, and building (and tracking) an
    object per row costs several times what the row itself does."""
    return (
        select(*_COLUMNS)
        .select_from(VehiclePosition)
        .join(Vehicle, VehiclePosition.vehicle_id == Vehicle.id)
        .outerjoin(MapVersion, VehiclePosition.map_version_id == MapVersion.id)
    )


def _views(session: Session, query: Select[*tuple[Any, ...]]) -> list[PositionView]:
    """The positions ``query`` selects, run on the session's connection: plain rows need none of the ORM's
    per-row loading, which costs as much again as the rows themselves."""
    result = session.connection().execute(query)
    return [PositionView(*row) for rows in result.partitions(1000) for row in rows]


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
    return _views(session, query.order_by(VehiclePosition.t_s).limit(limit))


def since(session: Session, seq: int, limit: int = 10000) -> list[PositionView]:
    """Positions of every vehicle with a sequence number above ``seq``, oldest first."""
    return _views(session, _query().where(VehiclePosition.id > seq).order_by(VehiclePosition.id).limit(limit))


def last_seq(session: Session) -> int:
    """The highest sequence number stored (0 before any position)."""
    return session.scalar(select(func.max(VehiclePosition.id))) or 0


def is_stale(position: PositionView | None, stale_after_s: float, now: datetime | None = None) -> bool:
    """Whether a vehicle whose last position is ``position`` counts as stale now."""
    if position is None:
        return True
    return ((now or utc_now()) - position.received_at).total_seconds() > stale_after_s


def latest(session: Session, stale_after_s: float, site_id: int | None = None) -> list[VehicleLatest]:
    """Every vehicle (of one site when given) with its last known position and stale flag.

    A vehicle's last position is its one of highest ``t`` (a vehicle's stored ``t`` only grows: a frame not
    after the last accepted one is refused), found through the ``(vehicle_id, t_s)`` index one vehicle at a
    time, so the cost does not grow with the history kept.
    """
    newest_id = (
        select(VehiclePosition.id)
        .where(VehiclePosition.vehicle_id == Vehicle.id)
        .order_by(VehiclePosition.t_s.desc())
        .limit(1)
        .scalar_subquery()
    )
    vehicles_query = select(Vehicle.id, Vehicle.name, Vehicle.site_id, newest_id).order_by(Vehicle.id)
    if site_id is not None:
        vehicles_query = vehicles_query.where(Vehicle.site_id == site_id)
    vehicles = session.execute(vehicles_query).all()
    ids = [position_id for *_, position_id in vehicles if position_id is not None]
    positions = {
        view.vehicle_id: view for view in _views(session, _query().where(VehiclePosition.id.in_(ids)))
    }
    now = utc_now()
    out = []
    for vehicle_id, name, vehicle_site_id, _ in vehicles:
        position = positions.get(vehicle_id)
        out.append(
            VehicleLatest(vehicle_id, name, vehicle_site_id, is_stale(position, stale_after_s, now), position)
        )
    return out
