"""What keeps the background work going, as the health check sees it: live job workers and a moving queue.

A job worker says it is alive on its ``workers`` row (:func:`worker_seen`, every reaper round) and removes
the row when it stops (:func:`worker_gone`). :func:`queue_state` tells whether queued jobs wait while
nothing moves: no job started, finished or beat its heartbeat for a while.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime, timedelta

from sqlalchemy import delete, func, or_, select, update
from sqlalchemy.orm import Session

from driftmap.store.db import Database
from driftmap.store.job_models import Job
from driftmap.store.models import utc_now
from driftmap.store.worker_models import WorkerProcess

FORGET_WORKER_AFTER_S = 24 * 3600.0
"""A worker row not refreshed for this long (its process was killed) is deleted, seconds."""


def worker_seen(db: Database, worker_id: str) -> None:
    """Record that worker ``worker_id`` is alive now; drop rows of workers gone for a day."""
    now = utc_now()
    with db.session() as session:
        found = session.execute(
            update(WorkerProcess).where(WorkerProcess.id == worker_id).values(seen_at=now)
        ).rowcount  # type: ignore[attr-defined]
        if not found:
            session.add(WorkerProcess(id=worker_id, started_at=now, seen_at=now))
        forget = now - timedelta(seconds=FORGET_WORKER_AFTER_S)
        session.execute(delete(WorkerProcess).where(WorkerProcess.seen_at < forget))


def worker_gone(db: Database, worker_id: str) -> None:
    """Remove the row of worker ``worker_id`` (it is stopping)."""
    with db.session() as session:
        session.execute(delete(WorkerProcess).where(WorkerProcess.id == worker_id))


def live_workers(session: Session, within_s: float) -> list[str]:
    """Ids of the workers seen in the last ``within_s`` seconds."""
    cutoff = utc_now() - timedelta(seconds=within_s)
    return list(session.scalars(select(WorkerProcess.id).where(WorkerProcess.seen_at >= cutoff)))


@dataclass(frozen=True)
class QueueState:
    """The jobs queue at a glance."""

    queued: int
    """Jobs waiting to run."""
    running: int
    """Jobs a worker runs."""
    oldest_queued_s: float | None
    """Age of the oldest waiting job, seconds (None when none waits)."""
    stalled: bool
    """Jobs wait, the oldest longer than the stall time, and no job started, finished or beat within it."""


def _age_s(at: datetime | None, now: datetime) -> float | None:
    if at is None:
        return None
    at = at if at.tzinfo is not None else at.replace(tzinfo=now.tzinfo)
    return (now - at).total_seconds()


def queue_state(session: Session, stall_after_s: float) -> QueueState:
    """How many jobs wait and run, and whether the queue is stalled (see :class:`QueueState`)."""
    now = utc_now()
    counts = dict(
        session.execute(
            select(Job.status, func.count()).where(Job.status.in_(("queued", "running"))).group_by(Job.status)
        ).all()
    )
    oldest = _age_s(session.scalar(select(func.min(Job.created_at)).where(Job.status == "queued")), now)
    cutoff = now - timedelta(seconds=stall_after_s)
    moved = session.scalar(
        select(func.count())
        .select_from(Job)
        .where(or_(Job.started_at >= cutoff, Job.finished_at >= cutoff, Job.heartbeat_at >= cutoff))
    )
    stalled = oldest is not None and oldest > stall_after_s and not moved
    return QueueState(int(counts.get("queued", 0)), int(counts.get("running", 0)), oldest, stalled)
