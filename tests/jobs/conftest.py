"""Fixtures of the job tests: a job runtime on the test's storage, and its queues (``mini_site`` is in
tests/conftest.py)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from driftmap.config import Settings
from driftmap.jobs.queue import JobQueue
from driftmap.jobs.runtime import JobRuntime
from driftmap.store.storage import Storage


@pytest.fixture
def runtime(settings: Settings, storage: Storage) -> JobRuntime:
    """What tasks run with: the test's storage, quick heartbeats, every progress report written."""
    return JobRuntime(settings=settings, storage=storage, heartbeat_s=0.2, progress_interval_s=0.0)


@pytest.fixture
def queue(settings: Settings, runtime: JobRuntime) -> Iterator[JobQueue]:
    """A queue whose tasks run as soon as they are enqueued (subtasks inside their parent's fan-out)."""
    yield JobQueue(settings, immediate=True, runtime=runtime)


@pytest.fixture
def stored_queue(settings: Settings, runtime: JobRuntime) -> JobQueue:
    """A queue on the SqliteHuey file of the data dir with no consumer: messages wait."""
    return JobQueue(settings, runtime=runtime)
