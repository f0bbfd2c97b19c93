"""Who may use the server and what the vehicles report: users, vehicles, position history, live state.

Positions are the localiser's continuous estimate in survey-frame metres (x east, y north), ``t_s`` is the
vehicle's own frame timestamp in seconds, ``received_at`` the server's UTC clock. A position's ``id`` is
the sequence number the live WebSocket uses to resume.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    Float,
    ForeignKey,
    Index,
    Integer,
    LargeBinary,
    String,
    UniqueConstraint,
)
from sqlalchemy.orm import Mapped, mapped_column

from driftmap.store.models import Base, UtcDateTime, utc_now


class User(Base):
    """A person who logs in; ``role`` is one of admin, surveyor, viewer.

    ``token_generation`` is written into every login token; raising it (logout, password, role change,
    disable) makes the user's outstanding tokens invalid. A user with ``disabled_at`` set cannot log in.
    """

    __tablename__ = "users"

    id: Mapped[int] = mapped_column(primary_key=True)
    username: Mapped[str] = mapped_column(String(100), unique=True)
    password_hash: Mapped[str] = mapped_column(String(200))
    """argon2id hash in PHC string format."""
    role: Mapped[str] = mapped_column(String(20))
    token_generation: Mapped[int] = mapped_column(Integer, default=0, server_default="0")
    """Login tokens carry the generation they were issued under; only the current one is accepted."""
    disabled_at: Mapped[datetime | None] = mapped_column(UtcDateTime(), nullable=True)
    """When an admin disabled the user (None: active)."""
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)
    updated_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now, onupdate=utc_now)


class Vehicle(Base):
    """A vehicle of a site that posts camera frames with its own API token (stored as a SHA-256)."""

    __tablename__ = "vehicles"
    __table_args__ = (UniqueConstraint("site_id", "name", name="uq_vehicles_site_id_name"),)

    id: Mapped[int] = mapped_column(primary_key=True)
    site_id: Mapped[int] = mapped_column(ForeignKey("sites.id", ondelete="CASCADE"), index=True)
    name: Mapped[str] = mapped_column(String(200))
    token_sha256: Mapped[str] = mapped_column(String(64))
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)
    token_rotated_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)
    camera: Mapped[dict[str, Any] | None] = mapped_column(JSON(none_as_null=True), nullable=True)
    """The vehicle camera's ``camera`` block (drive.json keys of formats.md), None when not calibrated."""

    @property
    def has_camera(self) -> bool:
        """Whether the vehicle has a calibrated camera (its frames then carry odometry)."""
        return self.camera is not None


class VehiclePosition(Base):
    """One localisation estimate of a vehicle (a processed live frame)."""

    __tablename__ = "vehicle_positions"
    __table_args__ = (
        Index("ix_vehicle_positions_vehicle_id_t_s", "vehicle_id", "t_s"),
        Index("ix_vehicle_positions_received_at", "received_at"),  # the history retention's passes
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    vehicle_id: Mapped[int] = mapped_column(ForeignKey("vehicles.id", ondelete="CASCADE"))
    map_version_id: Mapped[int | None] = mapped_column(
        ForeignKey("map_versions.id", ondelete="SET NULL"), nullable=True
    )
    t_s: Mapped[float] = mapped_column(Float)
    node: Mapped[int] = mapped_column(Integer)
    x_m: Mapped[float] = mapped_column(Float)
    y_m: Mapped[float] = mapped_column(Float)
    yaw_rad: Mapped[float | None] = mapped_column(Float, nullable=True)
    """Heading, radians counter-clockwise from +x (east); None when unknown."""
    confidence: Mapped[float] = mapped_column(Float)
    """The calibrated probability, 0-1, that the position is right."""
    matched: Mapped[bool] = mapped_column(Boolean)
    lost: Mapped[bool] = mapped_column(Boolean)
    received_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)
    # the obscured-camera judgement after this frame (driftmap.core.localisation.camera_check); None on older rows
    obscured: Mapped[bool | None] = mapped_column(Boolean, nullable=True)
    obscured_reason: Mapped[str | None] = mapped_column(String(16), nullable=True)
    """``dust``, ``water`` or ``covered`` when obscured."""
    salient: Mapped[float | None] = mapped_column(Float, nullable=True)
    sharpness: Mapped[float | None] = mapped_column(Float, nullable=True)
    speckle: Mapped[float | None] = mapped_column(Float, nullable=True)
    flat_area: Mapped[float | None] = mapped_column(Float, nullable=True)
    # the vehicle's motion at this frame; None on older rows (and speed when not measured)
    speed_mps: Mapped[float | None] = mapped_column(Float, nullable=True)
    """Speed from the camera odometry, metres per second (negative: reversing)."""
    moving: Mapped[bool | None] = mapped_column(Boolean, nullable=True)
    odometry: Mapped[bool | None] = mapped_column(Boolean, nullable=True)
    """This frame's motion came from the vehicle camera's odometry."""


class VehicleLiveState(Base):
    """A vehicle's localiser between frames, shared by every API process.

    ``revision`` is SQLAlchemy's version counter: two processes that both advance the same vehicle cannot
    both commit, so frames are never double-processed. ``state_npz`` is the ``.npz`` of
    :meth:`driftmap.core.localisation.localiser.LocaliserState.to_arrays` for ``map_version_id``.
    """

    __tablename__ = "vehicle_live_states"

    vehicle_id: Mapped[int] = mapped_column(ForeignKey("vehicles.id", ondelete="CASCADE"), primary_key=True)
    map_version_id: Mapped[int | None] = mapped_column(
        ForeignKey("map_versions.id", ondelete="SET NULL"), nullable=True
    )
    last_t_s: Mapped[float | None] = mapped_column(Float, nullable=True)
    """Timestamp of the last processed frame, seconds; a frame at or before it is out of order."""
    state_npz: Mapped[bytes | None] = mapped_column(LargeBinary, nullable=True)
    processed: Mapped[int] = mapped_column(Integer, default=0)
    skipped: Mapped[int] = mapped_column(Integer, default=0)
    """Frames dropped on purpose because a newer frame of the vehicle was waiting (overload)."""
    out_of_order: Mapped[int] = mapped_column(Integer, default=0)
    """Frames refused because their ``t`` was not after ``last_t_s``."""
    revision: Mapped[int] = mapped_column(Integer, default=0)
    updated_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now, onupdate=utc_now)
    reported_at: Mapped[datetime | None] = mapped_column(UtcDateTime(), nullable=True)
    """When the server received the vehicle's last position (None before its first); silence is read here."""
    low_confidence_since_s: Mapped[float | None] = mapped_column(Float, nullable=True)
    """``t`` of the first frame of the vehicle's current run of unmatched positions, seconds (None: matched)."""

    __mapper_args__ = {"version_id_col": revision}  # noqa: RUF012 (SQLAlchemy reads it as a class attribute)
