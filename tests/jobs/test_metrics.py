"""The worker's own metrics: every job run observed by kind and outcome, served by `driftmap worker --metrics-port`."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import httpx
import pytest
from prometheus_client.parser import text_string_to_metric_families

from driftmap.config import Settings
from driftmap.errors import BadInputError
from driftmap.jobs.metrics import WORKER_REGISTRY
from driftmap.jobs.queue import JobQueue
from driftmap.jobs.runtime import JobContext, JobRuntime, run_job
from driftmap.services import jobs as job_service
from driftmap.store.storage import Storage
from tests.processes import free_port, stop


def _runs(kind: str, outcome: str) -> float:
    value = WORKER_REGISTRY.get_sample_value("driftmap_job_seconds_count", {"kind": kind, "outcome": outcome})
    return value or 0.0


def _submit(storage: Storage, queue: JobQueue) -> int:
    with storage.db.session() as session:
        return job_service.submit(session, queue.enqueue, "site.simulate", {}).id


class TestObserved:
    def test_each_run_counts_under_its_kind_and_outcome(
        self, storage: Storage, runtime: JobRuntime, stored_queue: JobQueue
    ) -> None:
        def succeeds(ctx: JobContext) -> None:
            with storage.db.session() as session:
                ctx.succeed(session, {})

        def refuses(_ctx: JobContext) -> None:
            raise BadInputError("no such thing", field="size")

        before = _runs("site.simulate", "succeeded"), _runs("site.simulate", "failed")
        run_job(runtime, succeeds, "site.simulate", _submit(storage, stored_queue), stored_queue.enqueue)
        run_job(runtime, refuses, "site.simulate", _submit(storage, stored_queue), stored_queue.enqueue)
        after = _runs("site.simulate", "succeeded"), _runs("site.simulate", "failed")
        assert (after[0] - before[0], after[1] - before[1]) == (1.0, 1.0)


@pytest.mark.slow  # a real worker process
class TestServed:
    def test_a_worker_serves_its_metrics_on_its_port(self, settings: Settings) -> None:
        port = free_port()
        env = {**os.environ, "DRIFTMAP_DATA_DIR": str(settings.data_dir)}
        env.pop("DRIFTMAP_REDIS_URL", None)
        command = [sys.executable, "-m", "driftmap", "worker", "--metrics-port", str(port)]
        worker = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + 60.0
            while True:
                try:
                    text = httpx.get(f"http://127.0.0.1:{port}/metrics", timeout=2.0).text
                    break
                except httpx.TransportError:
                    assert worker.poll() is None and time.monotonic() < deadline
                    time.sleep(0.2)
        finally:
            stop(worker)
        names = {family.name for family in text_string_to_metric_families(text)}
        assert {"driftmap_job_seconds", "driftmap_worker_started_seconds"} <= names
