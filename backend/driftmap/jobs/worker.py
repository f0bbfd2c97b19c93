"""The worker process: a huey consumer running the job tasks, plus a reaper of jobs whose worker died.

``driftmap worker`` calls :func:`run_worker`. On start it upgrades the schema, removes scratch folders that
killed processes left behind, re-enqueues queued jobs that are not on the queue (an enqueue lost between a
commit and a crash), and starts the reaper thread: every
``reap_every_s`` it re-queues running jobs whose heartbeat is older than ``stale_after_s``
(:func:`driftmap.services.jobs.requeue_stale`) and records on its ``workers`` row that this worker is alive
(:func:`driftmap.services.supervision.worker_seen`, read by ``/api/health``). Several workers, on one machine with the SQLite queue or on
several with Redis, share the queue; the conditional updates on the jobs row make sure one job runs on one
worker at a time. A map build fans its drives out as ``map.drive`` subtasks and its loop-closure search as
``map.loops`` subtasks (:mod:`driftmap.jobs.map_tasks`): every worker takes them off the queue, and the
build's own worker runs those still queued, so more workers build a site faster and one worker alone never
waits on itself. On SIGINT the consumer finishes its running
jobs; on SIGTERM it stops at once, and the jobs it was running are put back on the queue before the process
exits.
"""

from __future__ import annotations

import logging
import math
import shutil
import threading
import time
from dataclasses import dataclass
from datetime import UTC, datetime

from sqlalchemy import select, update

from driftmap.config import Settings
from driftmap.jobs.queue import JobQueue
from driftmap.jobs.runtime import JobRuntime, process_worker_prefix
from driftmap.services import jobs as job_service
from driftmap.services import retention, supervision
from driftmap.store.job_models import Job
from driftmap.store.storage import Storage

log = logging.getLogger(__name__)

UPLOAD_SCRATCH_AGE_S = 6 * 3600.0  # an upload's scratch folder older than this belongs to no live request


@dataclass(frozen=True)
class WorkerTimings:
    """How a worker watches its jobs and those of dead workers."""

    heartbeat_s: float = 2.0
    """A running job's heartbeat is refreshed this often, seconds."""
    stale_after_s: float = 30.0
    """A running job with no heartbeat for this long is re-queued, seconds (several heartbeats)."""
    reap_every_s: float = 5.0
    """How often the reaper looks for stale jobs, seconds."""
    poll_max_s: float = 0.5
    """Longest wait between two looks at an empty queue, seconds."""


def enqueue_orphans(queue: JobQueue, storage: Storage) -> list[int]:
    """Enqueue the queued jobs that are not waiting on the queue; returns their ids."""
    waiting = queue.pending_job_ids()
    orphans = [
        (kind, job_id) for kind, job_id in job_service.queued_jobs(storage.db) if job_id not in waiting
    ]
    for kind, job_id in orphans:
        queue.enqueue(kind, job_id)
    return [job_id for _kind, job_id in orphans]


def release_own_jobs(queue: JobQueue, storage: Storage) -> list[int]:
    """Put the jobs still running in this process back on the queue (called when the worker stops)."""
    prefix = process_worker_prefix()
    released: list[tuple[str, int]] = []
    with storage.db.session() as session:
        rows = session.execute(
            select(Job.id, Job.kind).where(Job.status == "running", Job.worker_id.startswith(prefix))
        ).all()
        for job_id, kind in rows:
            moved = session.execute(
                update(Job)
                .where(Job.id == job_id, Job.status == "running", Job.worker_id.startswith(prefix))
                .values(status="queued", worker_id=None, stage="re-queued: its worker stopped")
            )
            if moved.rowcount == 1:  # type: ignore[attr-defined]
                released.append((kind, job_id))
    for kind, job_id in released:
        queue.enqueue(kind, job_id)
    return [job_id for _kind, job_id in released]


def sweep_scratch(settings: Settings, storage: Storage, *, upload_age_s: float = UPLOAD_SCRATCH_AGE_S) -> int:
    """Remove scratch folders a killed process left in ``<data_dir>/tmp``; returns how many.

    ``job-<id>-*`` folders go unless job ``id`` is running (on any worker); ``upload-*`` folders of API
    requests go once older than ``upload_age_s``.
    """
    root = settings.data_dir / "tmp"
    if not root.is_dir():
        return 0
    with storage.db.session() as session:
        running = {str(i) for i in session.scalars(select(Job.id).where(Job.status == "running"))}
    removed = 0
    for folder in root.iterdir():
        parts = folder.name.split("-")
        stale_job = parts[0] == "job" and len(parts) > 2 and parts[1] not in running
        old_upload = parts[0] == "upload" and time.time() - folder.stat().st_mtime > upload_age_s
        if folder.is_dir() and (stale_job or old_upload):
            shutil.rmtree(folder, ignore_errors=True)
            removed += 1
    return removed


class Reaper(threading.Thread):
    """Re-queues stale jobs every ``timings.reap_every_s`` until stopped, and applies the position history's
    retention (:mod:`driftmap.services.retention`) every ``history_every_s`` of ``settings`` (0: never)."""

    def __init__(
        self, queue: JobQueue, storage: Storage, timings: WorkerTimings, settings: Settings | None = None
    ) -> None:
        super().__init__(name="driftmap-reaper", daemon=True)
        self._queue, self._storage, self._timings = queue, storage, timings
        self._stop_event = threading.Event()
        self._retention = None
        self._retention_every_s = 0.0
        if settings is not None and settings.history_every_s > 0:
            self._retention = retention.RetentionPolicy.of(settings)
            self._retention_every_s = settings.history_every_s
        self._retained_at = -math.inf

    def run(self) -> None:
        while True:
            try:
                supervision.worker_seen(self._storage.db, process_worker_prefix())
                job_service.requeue_stale(self._storage.db, self._queue.enqueue, self._timings.stale_after_s)
            except Exception:
                log.warning("stale-job check failed", exc_info=True)
            self._retain()
            if self._stop_event.wait(self._timings.reap_every_s):
                return

    def _retain(self) -> None:
        if self._retention is None or time.monotonic() - self._retained_at < self._retention_every_s:
            return
        self._retained_at = time.monotonic()
        try:
            with self._storage.db.session() as session:
                done = retention.apply_retention(session, self._retention, datetime.now(UTC))
            if done.thinned or done.dropped or done.partitions_created or done.partitions_dropped:
                log.info(
                    "position history: %d thinned, %d past retention deleted; partitions created %s, dropped %s",
                    done.thinned,
                    done.dropped,
                    list(done.partitions_created),
                    list(done.partitions_dropped),
                )
            if done.partition_compacted:
                log.info("position history: thinned week %s compacted", done.partition_compacted)
            if done.events_dropped:
                log.info(
                    "event log: %d ended, acknowledged events past retention deleted", done.events_dropped
                )
        except Exception:
            log.warning("position history retention failed", exc_info=True)

    def stop(self) -> None:
        self._stop_event.set()
        self.join()


def run_worker(settings: Settings, *, workers: int = 1, timings: WorkerTimings | None = None) -> None:
    """Run a huey consumer with ``workers`` threads in this process until SIGINT or SIGTERM."""
    timings = timings or WorkerTimings()
    storage = Storage.open(settings)
    runtime = JobRuntime(settings=settings, storage=storage, heartbeat_s=timings.heartbeat_s)
    queue = JobQueue(settings, runtime=runtime)
    swept = sweep_scratch(settings, storage)
    if swept:
        log.warning("removed %d scratch folders left by stopped processes", swept)
    orphans = enqueue_orphans(queue, storage)
    if orphans:
        log.warning("enqueued %d queued jobs missing from the queue: %s", len(orphans), orphans)
    reaper = Reaper(queue, storage, timings, settings)
    reaper.start()
    consumer = queue.huey.create_consumer(
        workers=workers, worker_type="thread", periodic=False, max_delay=timings.poll_max_s
    )
    log.info("worker %s: %d thread(s) on %s", process_worker_prefix(), workers, type(queue.huey).__name__)
    try:
        consumer.run()
    finally:
        reaper.stop()
        released = release_own_jobs(queue, storage)
        if released:
            log.warning("re-queued jobs interrupted by the shutdown: %s", released)
        try:
            supervision.worker_gone(storage.db, process_worker_prefix())
        finally:
            storage.close()
