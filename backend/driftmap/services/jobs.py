"""Background jobs on the ``jobs`` table: submit, list, cancel, and the worker's side of a job's life.

The row is the truth; the queue (huey, see :mod:`driftmap.jobs.queue`) only carries job ids and is handed
in as an ``enqueue(kind, job_id)`` callable, so this module does not know which queue runs the jobs.

Life of a job::

    queued --claim--> running --finish--> succeeded | failed | cancelled
       \\--cancel--> cancelled      \\--worker lost (stale heartbeat)--> queued (again, up to MAX_ATTEMPTS)

Every state change is one conditional ``UPDATE ... WHERE status = ...`` so that two workers, a cancel and
the stale-job reaper can race without a job running twice at once or ending in two states. A task writes its
output and :func:`finish` in the same transaction, so a job has either all its output and ``succeeded`` or
none of it.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import timedelta
from typing import Any

from sqlalchemy import event, func, select, update
from sqlalchemy.orm import Session

from driftmap.errors import BadInputError, ConflictError, NotFoundError
from driftmap.store.db import Database
from driftmap.store.job_models import Job
from driftmap.store.models import utc_now

log = logging.getLogger(__name__)

JOB_KINDS = ("map.build", "drive.localise", "drive.import", "site.simulate")
"""The kinds a user submits (the API's)."""
SUBTASK_KINDS = ("map.drive", "map.loops")
"""Kinds a job submits as its own subtasks: ``map.drive``, one drive of a ``map.build``
(:mod:`driftmap.jobs.map_tasks`)."""
QUEUE_KINDS = JOB_KINDS + SUBTASK_KINDS
"""Every kind the queue runs."""
FINAL_STATUSES = frozenset({"succeeded", "failed", "cancelled"})
MAX_ATTEMPTS = 3
"""A job whose worker died (or that hit an unexpected error) this many times is marked failed."""

Enqueue = Callable[[str, int], None]
"""Puts job ``job_id`` of kind ``kind`` on the queue."""


class JobCancelled(Exception):  # noqa: N818 (a signal, not an error)
    """Raised from a running job's progress hook when somebody asked to cancel it."""


class JobLost(Exception):  # noqa: N818 (a signal, not an error)
    """Raised when this worker no longer owns the job (re-queued as stale, or finished elsewhere)."""


def submit(
    session: Session,
    enqueue: Enqueue,
    kind: str,
    args: dict[str, Any],
    *,
    site_id: int | None = None,
    created_by: str = "",
    parent_id: int | None = None,
) -> Job:
    """Add a queued job row; it is put on the queue (by id) once ``session`` commits.

    ``parent_id`` makes it a subtask of that job: cancelled with it, deleted with it.

    Enqueueing after the commit means a worker never sees an id whose row it cannot read yet, and a
    rolled-back request enqueues nothing.
    """
    kinds = JOB_KINDS if parent_id is None else SUBTASK_KINDS
    if kind not in kinds:
        raise BadInputError(f"unknown job kind {kind!r}; one of {', '.join(kinds)}", field="kind")
    job = Job(
        kind=kind, site_id=site_id, args=args, status="queued", created_by=created_by, parent_id=parent_id
    )
    session.add(job)
    session.flush()
    job_id = job.id

    def _enqueue_after_commit(_session: Session) -> None:
        try:
            enqueue(kind, job_id)
        except Exception:  # the row stays queued; `driftmap worker` re-enqueues queued jobs on start
            log.exception("could not enqueue job %s (%s)", job_id, kind)

    event.listen(session, "after_commit", _enqueue_after_commit, once=True)
    return job


def get_job(session: Session, job_id: int) -> Job:
    """The job with that id."""
    job = session.get(Job, job_id)
    if job is None:
        raise NotFoundError(f"no job with id {job_id}")
    return job


def list_jobs(
    session: Session,
    *,
    site_id: int | None = None,
    status: str | None = None,
    kind: str | None = None,
    parent_id: int | None = None,
    offset: int = 0,
    limit: int = 50,
) -> tuple[list[Job], int]:
    """Jobs matching the filters, newest first, and how many match in all: the top-level jobs, or the
    subtasks of job ``parent_id``."""
    query = select(Job).where(Job.parent_id.is_(None) if parent_id is None else Job.parent_id == parent_id)
    if site_id is not None:
        query = query.where(Job.site_id == site_id)
    if status is not None:
        query = query.where(Job.status == status)
    if kind is not None:
        query = query.where(Job.kind == kind)
    total = session.scalar(select(func.count()).select_from(query.subquery())) or 0
    rows = session.scalars(query.order_by(Job.id.desc()).offset(offset).limit(limit)).all()
    return list(rows), total


def cancel(session: Session, job_id: int) -> Job:
    """Cancel a job: a queued one never starts; a running one stops at its next progress report.

    Its unfinished subtasks (``parent_id`` = ``job_id``) are cancelled the same way.

    Raises:
        NotFoundError: no such job.
        ConflictError: the job has already finished.
    """
    _cancel_rows(session, Job.id == job_id)
    cancel_children(session, job_id)
    job = get_job(session, job_id)
    session.refresh(job)
    if job.status in ("succeeded", "failed"):
        raise ConflictError(f"job {job_id} has already {job.status}")
    return job


def _cancel_rows(session: Session, which: Any) -> None:
    """Cancel the queued jobs matching ``which`` and ask the running ones to stop."""
    now = utc_now()
    session.execute(
        update(Job)
        .where(which, Job.status == "queued")
        .values(status="cancelled", finished_at=now, stage="cancelled before it started")
    )
    session.execute(
        update(Job)
        .where(which, Job.status == "running", Job.cancel_requested_at.is_(None))
        .values(cancel_requested_at=now)
    )


def cancel_children(session: Session, parent_id: int) -> None:
    """Cancel the unfinished subtasks of job ``parent_id`` (queued: at once; running: at their next report)."""
    _cancel_rows(session, Job.parent_id == parent_id)


def children(session: Session, parent_id: int) -> list[Job]:
    """The subtasks of job ``parent_id``, oldest first."""
    return list(session.scalars(select(Job).where(Job.parent_id == parent_id).order_by(Job.id)))


# ---------------------------------------------------------------------------------------------------
# The worker's side


def claim(db: Database, job_id: int, worker_id: str) -> Job | None:
    """Mark a queued job running for ``worker_id``; None when it is not queued (cancelled, done, taken)."""
    now = utc_now()
    with db.session() as session:
        taken = session.execute(
            update(Job)
            .where(Job.id == job_id, Job.status == "queued")
            .values(
                status="running",
                attempts=Job.attempts + 1,
                started_at=now,
                heartbeat_at=now,
                worker_id=worker_id,
                stage="starting",
                progress=0.0,
            )
        )
        if taken.rowcount != 1:  # type: ignore[attr-defined]
            return None
        return session.get(Job, job_id)


def finish(
    session: Session,
    job_id: int,
    worker_id: str,
    status: str,
    *,
    result: dict[str, Any] | None = None,
    error: str | None = None,
) -> None:
    """Record the end of a job this worker runs, in ``session``'s transaction.

    Raises:
        JobLost: the job is no longer running for ``worker_id``; the caller must roll back its output.
    """
    assert status in FINAL_STATUSES
    values: dict[str, Any] = {"status": status, "finished_at": utc_now(), "error": error, "result": result}
    if status == "succeeded":
        values |= {"progress": 1.0, "stage": "done"}
    done = session.execute(
        update(Job)
        .where(Job.id == job_id, Job.worker_id == worker_id, Job.status == "running")
        .values(values)
    )
    if done.rowcount != 1:  # type: ignore[attr-defined]
        raise JobLost(f"job {job_id} is no longer running on {worker_id}")


def release_for_retry(db: Database, job_id: int, worker_id: str, error: str) -> bool:
    """After an unexpected error: back to queued when attempts remain (True), else failed (False)."""
    with db.session() as session:
        job = session.get(Job, job_id)
        if job is None or job.status != "running" or job.worker_id != worker_id:
            return False
        retry = job.attempts < MAX_ATTEMPTS
        job.status = "queued" if retry else "failed"
        job.error = error
        job.worker_id = None
        job.stage = "waiting to retry" if retry else job.stage
        job.finished_at = None if retry else utc_now()
        return retry


@dataclass
class ProgressReporter:
    """The ``report(stage, fraction)`` hook a running job calls; writes at most every ``interval_s``.

    Each write is its own short transaction (progress, stage, heartbeat) that also reads whether a cancel
    was requested: then it raises :class:`JobCancelled`; if the job was taken from this worker,
    :class:`JobLost`.
    """

    db: Database
    job_id: int
    worker_id: str
    interval_s: float = 0.5
    _last_write: float = 0.0
    _last_stage: str = ""

    def __call__(self, stage: str, fraction: float) -> None:
        now = time.monotonic()
        if stage == self._last_stage and now - self._last_write < self.interval_s:
            return
        self._last_write, self._last_stage = now, stage
        with self.db.session() as session:
            session.execute(
                update(Job)
                .where(Job.id == self.job_id, Job.worker_id == self.worker_id, Job.status == "running")
                .values(progress=min(max(float(fraction), 0.0), 1.0), stage=stage, heartbeat_at=utc_now())
            )
            row = session.execute(
                select(Job.status, Job.worker_id, Job.cancel_requested_at).where(Job.id == self.job_id)
            ).one_or_none()
        if row is None or row.status != "running" or row.worker_id != self.worker_id:
            raise JobLost(f"job {self.job_id} is no longer running on {self.worker_id}")
        if row.cancel_requested_at is not None:
            raise JobCancelled(f"job {self.job_id} was cancelled")


def beat(db: Database, job_id: int, worker_id: str) -> None:
    """Refresh the heartbeat of a job this worker runs (called from a timer thread)."""
    with db.session() as session:
        session.execute(
            update(Job)
            .where(Job.id == job_id, Job.worker_id == worker_id, Job.status == "running")
            .values(heartbeat_at=utc_now())
        )


def requeue_stale(db: Database, enqueue: Enqueue, stale_after_s: float) -> list[int]:
    """Re-queue running jobs whose heartbeat is older than ``stale_after_s`` (their worker died).

    A job that was asked to cancel is cancelled instead; one that has used up :data:`MAX_ATTEMPTS` is
    failed. Returns the ids put back on the queue.
    """
    cutoff = utc_now() - timedelta(seconds=stale_after_s)
    requeued: list[tuple[str, int]] = []
    with db.session() as session:
        stale = session.execute(
            select(Job.id, Job.kind, Job.attempts, Job.cancel_requested_at).where(
                Job.status == "running", Job.heartbeat_at < cutoff
            )
        ).all()
        for job_id, kind, attempts, cancel_requested in stale:
            if cancel_requested is not None:
                values: dict[str, Any] = {"status": "cancelled", "finished_at": utc_now()}
            elif attempts >= MAX_ATTEMPTS:
                values = {
                    "status": "failed",
                    "finished_at": utc_now(),
                    "error": f"its worker was lost {attempts} times",
                }
            else:
                values = {"status": "queued", "stage": "re-queued: its worker stopped responding"}
            moved = session.execute(
                update(Job)
                .where(Job.id == job_id, Job.status == "running", Job.heartbeat_at < cutoff)
                .values(worker_id=None, **values)
            )
            if moved.rowcount == 1 and values["status"] == "queued":  # type: ignore[attr-defined]
                requeued.append((kind, job_id))
    for kind, job_id in requeued:
        log.warning("re-queued job %s (%s): its worker stopped responding", job_id, kind)
        enqueue(kind, job_id)
    return [job_id for _kind, job_id in requeued]


def queued_jobs(db: Database) -> list[tuple[str, int]]:
    """(kind, id) of every queued job, oldest first (re-enqueued when a worker starts)."""
    with db.session() as session:
        rows = session.execute(select(Job.kind, Job.id).where(Job.status == "queued").order_by(Job.id))
        return [(kind, job_id) for kind, job_id in rows]
