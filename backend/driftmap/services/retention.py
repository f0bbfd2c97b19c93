"""Position history that lasts: every position for a while, then a thinned history, then none.

Every processed live frame stores a position row; at 10 frames a second that is 864,000 rows per vehicle-day.
The retention policy (:class:`RetentionPolicy`, from the ``DRIFTMAP_HISTORY_*`` settings) keeps

* every position received in the last ``full_days``;
* older ones thinned to the first position of every ``downsample_s`` seconds per vehicle (a trail a control
  room or an export can still follow: at 10 s, 8,640 rows per vehicle-day, a hundredth);
* none older than ``keep_days``.

The age of a position is by ``received_at`` (server time). :func:`apply_retention` is idempotent and safe
when several workers run it at once: the positions a pass keeps are fixed by the rows (the smallest id of
each vehicle and time bucket), so two passes delete the same rows. A pass thins only the positions that aged
past ``full_days`` within the last ``catch_up_days`` (bounded work per pass, whatever the history's length);
positions of a longer stop of every worker stay at full rate until they are deleted.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import BigInteger, ColumnElement, and_, cast, delete, func, select
from sqlalchemy.orm import Session

from driftmap.config import Settings
from driftmap.errors import BadInputError
from driftmap.store.access_models import VehiclePosition

__all__ = ["RetentionPolicy", "RetentionResult", "apply_retention"]


@dataclass(frozen=True)
class RetentionPolicy:
    """How long position history is kept (see the module doc); days and seconds."""

    full_days: float = 7.0
    downsample_s: float = 10.0
    keep_days: float = 365.0
    catch_up_days: float = 7.0

    def __post_init__(self) -> None:
        for name in ("full_days", "downsample_s", "keep_days", "catch_up_days"):
            value = getattr(self, name)
            if not value >= 0:
                raise BadInputError(f"history_{name} must be >= 0, got {value}", field=f"history_{name}")
        if self.keep_days and self.keep_days < self.full_days:
            raise BadInputError(
                f"history_keep_days ({self.keep_days}) must be 0 or at least history_full_days ({self.full_days})",
                field="history_keep_days",
            )

    @classmethod
    def of(cls, settings: Settings) -> RetentionPolicy:
        return cls(
            settings.history_full_days,
            settings.history_downsample_s,
            settings.history_keep_days,
            settings.history_catch_up_days,
        )


@dataclass(frozen=True)
class RetentionResult:
    """Rows deleted by one pass."""

    thinned: int
    dropped: int


def apply_retention(session: Session, policy: RetentionPolicy, now: datetime) -> RetentionResult:
    """Apply ``policy`` to the stored positions at time ``now`` (timezone-aware UTC); the caller commits."""
    dropped = 0
    if policy.keep_days > 0:
        cutoff = now - timedelta(days=policy.keep_days)
        dropped = _deleted(
            session.execute(delete(VehiclePosition).where(VehiclePosition.received_at < cutoff))
        )
    thinned = 0
    bucket_s = round(policy.downsample_s)
    if bucket_s > 0:
        end = now - timedelta(days=policy.full_days)
        start = end - timedelta(days=policy.catch_up_days)
        window = and_(VehiclePosition.received_at >= start, VehiclePosition.received_at < end)
        epoch: ColumnElement[Any] = func.extract("epoch", VehiclePosition.received_at)
        if session.get_bind().dialect.name != "sqlite":  # SQLite's epoch is whole seconds already
            epoch = func.floor(epoch)  # PostgreSQL's has a fraction, which a cast would round
        bucket = cast(epoch, BigInteger) // bucket_s
        kept = (
            select(func.min(VehiclePosition.id))
            .where(window)
            .group_by(VehiclePosition.vehicle_id, bucket)
            .scalar_subquery()
        )
        thinned = _deleted(
            session.execute(delete(VehiclePosition).where(window, VehiclePosition.id.not_in(kept)))
        )
    return RetentionResult(thinned, dropped)


def _deleted(result: object) -> int:
    count = getattr(result, "rowcount", 0)
    return int(count) if isinstance(count, int) and count >= 0 else 0
