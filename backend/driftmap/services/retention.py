"""Position history that lasts: every position for a while, then a thinned history, then none.

Every processed live frame stores a position row; at 10 frames a second that is 864,000 rows per vehicle-day.
The retention policy (:class:`RetentionPolicy`, from the ``DRIFTMAP_HISTORY_*`` settings) keeps

* every position received in the last ``full_days``;
* older ones thinned to the first position of every ``downsample_s`` seconds per vehicle (a trail a control
  room or an export can still follow: at 10 s, 8,640 rows per vehicle-day, a hundredth);
* none older than ``keep_days``.

The event log (:class:`~driftmap.store.event_models.VehicleEvent`) follows the same ``keep_days``: an event
that ended and was acknowledged more than ``keep_days`` ago is deleted; an open event or one nobody
acknowledged stays, however old (the control room still has to see it).

The age of a position is by ``received_at`` (server time). :func:`apply_retention` is idempotent and safe
when several workers run it at once: the positions a pass keeps are fixed by the rows (the smallest id of
each vehicle and time bucket), so two passes delete the same rows. A pass thins only the positions that aged
past ``full_days`` within the last ``catch_up_days`` (bounded work per pass, whatever the history's length);
positions of a longer stop of every worker stay at full rate until they are deleted.

On PostgreSQL the positions table is partitioned by week of ``received_at``
(:mod:`driftmap.store.position_partitions`): a pass first creates the coming weeks' partitions and drops every
partition that lies wholly past ``keep_days`` (one ``DROP TABLE`` instead of deleting its rows), then deletes
row by row only what is left past ``keep_days`` (the boundary week, the default partition) and thins as above;
last it rewrites one week whose rows are all thinned, to give back the disk its deleted rows held
(:func:`~driftmap.store.position_partitions.compact`).
Only one worker's pass does that upkeep at a time (an advisory lock; the others skip it); a pass whose upkeep
cannot get a table lock within a few seconds leaves it to the next pass and still thins and deletes.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

from sqlalchemy import BigInteger, ColumnElement, and_, cast, delete, func, select
from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session

from driftmap.config import Settings
from driftmap.errors import BadInputError
from driftmap.store import position_partitions
from driftmap.store.access_models import VehiclePosition
from driftmap.store.event_models import VehicleEvent

__all__ = ["RetentionPolicy", "RetentionResult", "apply_retention"]

log = logging.getLogger(__name__)


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
    """Rows deleted by one pass, and on PostgreSQL the weekly partitions it created and dropped (names)."""

    thinned: int
    dropped: int
    partitions_created: tuple[str, ...] = ()
    partitions_dropped: tuple[str, ...] = ()
    partition_compacted: str | None = None
    events_dropped: int = 0
    """Ended, acknowledged events deleted for being older than ``keep_days``."""


def apply_retention(session: Session, policy: RetentionPolicy, now: datetime) -> RetentionResult:
    """Apply ``policy`` to the stored positions at time ``now`` (timezone-aware UTC); the caller commits."""
    cutoff = now - timedelta(days=policy.keep_days) if policy.keep_days > 0 else None
    partitioned = position_partitions.is_partitioned(session.connection())
    upkeep = _partition_upkeep(session, now, cutoff) if partitioned else position_partitions.Upkeep((), ())
    dropped = events_dropped = 0
    if cutoff is not None:
        dropped = _deleted(
            session.execute(delete(VehiclePosition).where(VehiclePosition.received_at < cutoff))
        )
        events_dropped = _drop_old_events(session, cutoff)
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
    compacted = None
    if partitioned and upkeep.locked:
        compacted = _compact(session, now - timedelta(days=policy.full_days), cutoff)
    return RetentionResult(thinned, dropped, upkeep.created, upkeep.dropped, compacted, events_dropped)


def _drop_old_events(session: Session, cutoff: datetime) -> int:
    """Delete the events that ended and were acknowledged before ``cutoff``; how many."""
    old = delete(VehicleEvent).where(
        VehicleEvent.ended_at < cutoff,
        VehicleEvent.acknowledged_at.is_not(None),
        VehicleEvent.acknowledged_at < cutoff,
    )
    return _deleted(session.execute(old))


def _partition_upkeep(session: Session, now: datetime, cutoff: datetime | None) -> position_partitions.Upkeep:
    """Create the coming weeks' partitions, drop those wholly before ``cutoff``; in a savepoint, so a lock
    timeout gives up only the upkeep."""
    try:
        with session.begin_nested():
            return position_partitions.upkeep(session.connection(), now, cutoff)
    except OperationalError:
        log.warning(
            "position partitions: upkeep gave up (a table lock was busy); next pass retries", exc_info=True
        )
        return position_partitions.Upkeep((), (), locked=False)


def _deleted(result: object) -> int:
    count = getattr(result, "rowcount", 0)
    return int(count) if isinstance(count, int) and count >= 0 else 0


def _compact(session: Session, thinned_before: datetime, cutoff: datetime | None) -> str | None:
    """Rewrite one fully thinned week (PostgreSQL), in a savepoint like :func:`_partition_upkeep`."""
    try:
        with session.begin_nested():
            return position_partitions.compact(session.connection(), thinned_before, cutoff)
    except OperationalError:
        log.warning(
            "position partitions: compaction gave up (a table lock was busy); next pass retries",
            exc_info=True,
        )
        return None
