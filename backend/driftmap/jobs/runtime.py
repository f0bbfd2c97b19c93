"""Running one job: claim its row, keep its heartbeat, give its task a progress hook, record the outcome.

:func:`run_job` is the body of every huey task. The outcome of a task is decided here:

- it returned: the task itself recorded ``succeeded`` in the transaction that wrote its output;
- :class:`~driftmap.services.jobs.JobCancelled` (raised by the progress hook): ``cancelled``;
- a :class:`~driftmap.errors.DriftmapError` (bad input, missing site...): ``failed`` with its message, no retry;
- any other exception: the row goes back to ``queued`` and the exception propagates so that huey runs the
  task again after its retry delay, up to :data:`~driftmap.services.jobs.MAX_ATTEMPTS` attempts.

A worker that dies (SIGKILL, power loss) stops refreshing the heartbeat; the reaper of any live worker
(:func:`driftmap.services.jobs.requeue_stale`) then puts the job back on the queue.
"""

from __future__ import annotations

import logging
import os
import socket
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy.orm import Session

from driftmap.config import Settings
from driftmap.errors import DriftmapError
from driftmap.jobs.metrics import observe_job
from driftmap.services import jobs as job_service
from driftmap.store.job_models import Job
from driftmap.store.storage import Storage

log = logging.getLogger(__name__)


def process_worker_prefix() -> str:
    """``host:pid:`` — the start of the worker id of every job this process runs."""
    return f"{socket.gethostname()}:{os.getpid()}:"


@dataclass
class JobRuntime:
    """What tasks run with: settings, open storage, and the heartbeat/progress timings."""

    settings: Settings
    storage: Storage
    heartbeat_s: float = 2.0
    """How often a running job's heartbeat is refreshed, seconds."""
    progress_interval_s: float = 0.5
    """Least time between two progress writes of one job (stage changes are written at once), seconds."""


@dataclass
class JobContext:
    """One run of one job, handed to its task function."""

    runtime: JobRuntime
    job: Job
    worker_id: str
    report: Callable[[str, float], None]
    """``report(stage, fraction)``: progress hook; raises JobCancelled when the job was cancelled."""
    enqueue: job_service.Enqueue = field(repr=False)

    @property
    def args(self) -> dict[str, Any]:
        return dict(self.job.args or {})

    def succeed(self, session: Session, result: dict[str, Any]) -> None:
        """Mark the job succeeded inside ``session``'s transaction (the one writing its output)."""
        job_service.finish(session, self.job.id, self.worker_id, "succeeded", result=result)


@contextmanager
def heartbeat(runtime: JobRuntime, job_id: int, worker_id: str) -> Iterator[None]:
    """Refresh the job's heartbeat every ``runtime.heartbeat_s`` while the block runs."""
    stop = threading.Event()

    def loop() -> None:
        while not stop.wait(runtime.heartbeat_s):
            try:
                job_service.beat(runtime.storage.db, job_id, worker_id)
            except Exception:  # a busy database must not kill the job; the next beat tries again
                log.warning("heartbeat of job %s failed", job_id, exc_info=True)

    thread = threading.Thread(target=loop, name=f"heartbeat-{job_id}", daemon=True)
    thread.start()
    try:
        yield
    finally:
        stop.set()
        thread.join()


def _end(runtime: JobRuntime, job_id: int, worker_id: str, status: str, error: str | None = None) -> None:
    try:
        with runtime.storage.db.session() as session:
            job_service.finish(session, job_id, worker_id, status, error=error)
    except job_service.JobLost:
        log.info("job %s: no longer ours, outcome %s not recorded", job_id, status)


TaskFn = Callable[[JobContext], None]


def run_job(runtime: JobRuntime, task: TaskFn, kind: str, job_id: int, enqueue: job_service.Enqueue) -> None:
    """Run job ``job_id`` with ``task`` if it is still queued (see the module docstring for the outcomes)."""
    worker_id = f"{process_worker_prefix()}{uuid.uuid4().hex[:8]}"
    job = job_service.claim(runtime.storage.db, job_id, worker_id)
    if job is None:
        log.info("job %s (%s) is not queued any more; skipped", job_id, kind)
        return
    reporter = job_service.ProgressReporter(
        runtime.storage.db, job_id, worker_id, interval_s=runtime.progress_interval_s
    )
    context = JobContext(runtime, job, worker_id, reporter, enqueue)
    log.info("job %s (%s) attempt %d on %s", job_id, kind, job.attempts, worker_id)
    started, outcome = time.monotonic(), "succeeded"
    with heartbeat(runtime, job_id, worker_id):
        try:
            task(context)
        except job_service.JobCancelled:
            outcome = "cancelled"
            _end(runtime, job_id, worker_id, "cancelled")
        except job_service.JobLost:
            outcome = "lost"
            log.warning("job %s was taken from %s; its output was rolled back", job_id, worker_id)
        except DriftmapError as exc:
            outcome = "failed"
            _end(runtime, job_id, worker_id, "failed", str(exc))
        except Exception as exc:
            outcome = "failed"
            log.exception("job %s (%s) hit an unexpected error", job_id, kind)
            if job_service.release_for_retry(
                runtime.storage.db, job_id, worker_id, f"{type(exc).__name__}: {exc}"
            ):
                outcome = "retried"
                raise  # huey runs the task again after its retry delay
        finally:
            observe_job(kind, outcome, time.monotonic() - started)
