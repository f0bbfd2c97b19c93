"""The control room's event log: one row per condition of a vehicle, from its start to its end, and who
acknowledged it.

Kinds (:data:`EVENT_KINDS`): ``lost`` (the localiser is lost), ``obscured`` (the camera looks obscured),
``low_confidence`` (the vehicle's positions stayed under the match confidence for a while), ``stale`` (the
vehicle stopped reporting) and ``start_known`` (a user set the vehicle's known start: an instant, ended when
it starts). An event is open while ``ended_at`` is None. At most one event of each kind is open per vehicle
(a partial unique index), so API processes that notice the same condition at once cannot open it twice.
Times are the server's UTC clock; the position is the vehicle's last known one when the event started,
survey-frame metres (x east, y north).
"""

from __future__ import annotations

from datetime import datetime
from typing import Literal, get_args

from sqlalchemy import CheckConstraint, Float, ForeignKey, Index, String, text
from sqlalchemy.orm import Mapped, mapped_column

from driftmap.store.models import Base, UtcDateTime, utc_now

EventKind = Literal["lost", "obscured", "low_confidence", "stale", "start_known"]
EVENT_KINDS: tuple[str, ...] = get_args(EventKind)
_OPEN = text("ended_at IS NULL")


class VehicleEvent(Base):
    """One event of a vehicle: a condition (``kind``) from ``started_at`` to ``ended_at`` (None: still on)."""

    __tablename__ = "events"
    __table_args__ = (
        Index(
            "uq_events_vehicle_id_kind_open",
            "vehicle_id",
            "kind",
            unique=True,
            sqlite_where=_OPEN,
            postgresql_where=_OPEN,
        ),
        Index("ix_events_started_at", "started_at"),
        Index("ix_events_updated_at", "updated_at"),  # a watcher catching up after falling behind
        CheckConstraint(f"kind IN ({', '.join(repr(k) for k in EVENT_KINDS)})", name="kind"),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    site_id: Mapped[int] = mapped_column(ForeignKey("sites.id", ondelete="CASCADE"), index=True)
    vehicle_id: Mapped[int] = mapped_column(ForeignKey("vehicles.id", ondelete="CASCADE"))
    kind: Mapped[str] = mapped_column(String(20))
    detail: Mapped[str | None] = mapped_column(String(200), nullable=True)
    """A few words on the condition: the obscured camera's reason, the known start's radius."""
    started_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)
    ended_at: Mapped[datetime | None] = mapped_column(UtcDateTime(), nullable=True)
    """When the condition ended ("found again", "camera clear", "back"); None while it lasts."""
    x_m: Mapped[float | None] = mapped_column(Float, nullable=True)
    """The vehicle's last known position when the event started, survey-frame metres east (None: none)."""
    y_m: Mapped[float | None] = mapped_column(Float, nullable=True)
    """... metres north."""
    acknowledged_by_id: Mapped[int | None] = mapped_column(
        ForeignKey("users.id", ondelete="SET NULL"), nullable=True
    )
    acknowledged_by: Mapped[str | None] = mapped_column(String(100), nullable=True)
    """The acknowledging user's name, kept when the user is deleted."""
    acknowledged_at: Mapped[datetime | None] = mapped_column(UtcDateTime(), nullable=True)
    updated_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now, onupdate=utc_now)
    """When the event last changed (opened, ended or acknowledged)."""
