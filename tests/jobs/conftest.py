"""Fixtures of the job tests: the mini site, a job runtime on the test's storage, and its queues."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from driftmap.config import Settings
from driftmap.jobs.queue import JobQueue
from driftmap.jobs.runtime import JobRuntime
from driftmap.store.storage import Storage
from tests.jobs.mini_site import mini_site_dir


@pytest.fixture(scope="session")
def mini_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The mini simulated site (100 frames per drive), made once per test process."""
    return mini_site_dir(tmp_path_factory)


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
