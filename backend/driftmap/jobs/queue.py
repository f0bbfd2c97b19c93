"""The huey queue: :class:`huey.SqliteHuey` under the data dir by default, :class:`huey.RedisHuey` with Redis.

Each job kind (``map.build`` and its ``map.drive`` subtasks, ``drive.localise``, ``drive.import``,
``site.simulate``) is one huey task named after it that takes only the job id; the ``jobs`` row holds the arguments and the state. The API process only
enqueues; a worker process (:mod:`driftmap.jobs.worker`) runs the tasks. In ``immediate`` mode (unit tests)
huey runs a task in the calling thread as soon as it is enqueued.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any

from huey import Huey, RedisHuey, SqliteHuey

from driftmap.config import Settings
from driftmap.jobs.runtime import JobRuntime, run_job
from driftmap.jobs.tasks import TASKS
from driftmap.services.jobs import MAX_ATTEMPTS, QUEUE_KINDS
from driftmap.store.storage import Storage

log = logging.getLogger(__name__)

QUEUE_NAME = "driftmap"
RETRY_DELAY_S = 2.0  # huey waits this long before running a job again after an unexpected error


def make_huey(settings: Settings, *, immediate: bool = False) -> Huey:
    """The huey instance of ``settings``: Redis when ``redis_url`` is set, else ``<data_dir>/queue.db``."""
    if settings.redis_url:
        return RedisHuey(QUEUE_NAME, url=settings.redis_url, results=False, immediate=immediate)
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    return SqliteHuey(
        QUEUE_NAME,
        filename=str(settings.data_dir / "queue.db"),
        results=False,
        immediate=immediate,
        timeout=30,
    )


class JobQueue:
    """The queue of ``settings`` with one huey task per job kind.

    Args:
        settings: where the queue (and, for running tasks, the database) lives.
        immediate: run tasks in the enqueuing thread (huey's immediate mode; unit tests only).
        runtime: what running tasks use; opened from ``settings`` on first use when not given.
    """

    def __init__(
        self, settings: Settings, *, immediate: bool = False, runtime: JobRuntime | None = None
    ) -> None:
        self.settings = settings
        self.huey = make_huey(settings, immediate=immediate)
        self._runtime = runtime
        self._tasks: dict[str, Callable[..., Any]] = {kind: self._register(kind) for kind in QUEUE_KINDS}

    def runtime(self) -> JobRuntime:
        """The storage and timings tasks run with (opened lazily: the API process never runs tasks)."""
        if self._runtime is None:
            self._runtime = JobRuntime(settings=self.settings, storage=Storage.open(self.settings))
        return self._runtime

    def _register(self, kind: str) -> Callable[..., Any]:
        def run(job_id: int) -> None:
            run_job(self.runtime(), TASKS[kind], kind, job_id, self.enqueue)

        run.__name__ = kind.replace(".", "_")
        task: Callable[..., Any] = self.huey.task(name=kind, retries=MAX_ATTEMPTS, retry_delay=RETRY_DELAY_S)(
            run
        )
        return task

    def enqueue(self, kind: str, job_id: int) -> None:
        """Put job ``job_id`` of ``kind`` on the queue (the row must already be committed)."""
        self._tasks[kind](job_id)

    def pending_job_ids(self) -> set[int]:
        """Ids of jobs waiting on the queue or scheduled for a retry (not those being run)."""
        waiting = [*self.huey.pending(), *self.huey.scheduled()]
        return {int(task.args[0]) for task in waiting if task.name in QUEUE_KINDS and task.args}

    def close(self) -> None:
        """Close the storage a task runtime opened."""
        if self._runtime is not None:
            self._runtime.storage.close()
            self._runtime = None
