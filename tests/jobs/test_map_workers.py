"""A fanned-out map build on real ``driftmap worker`` processes sharing one queue and one database."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from sqlalchemy import func, select

from driftmap.config import Settings
from driftmap.jobs.queue import JobQueue
from driftmap.services import jobs as job_service
from driftmap.services import sites as site_service
from driftmap.store.job_models import Job
from driftmap.store.models import Frame, MapPose, MapVersion
from driftmap.store.storage import Storage
from tests.api.data_helpers import stop_worker
from tests.sim_site import import_site

DEADLINE_S = 300.0  # a build of the mini site on a loaded 2-core machine


def _submit(storage: Storage, settings: Settings) -> int:
    with storage.db.session() as session:
        site_id = site_service.get_site(session, "tiny").id
        queue = JobQueue(settings)
        return job_service.submit(
            session, queue.enqueue, "map.build", {"preset": "paper"}, site_id=site_id
        ).id


def _wait(storage: Storage, what: Callable[[Job, list[Job]], bool], job_id: int) -> tuple[Job, list[Job]]:
    deadline = time.monotonic() + DEADLINE_S
    while True:
        with storage.db.session() as session:
            parent, subtasks = job_service.get_job(session, job_id), job_service.children(session, job_id)
        if what(parent, subtasks):
            return parent, subtasks
        assert time.monotonic() < deadline, (parent.status, parent.stage, [s.status for s in subtasks])
        time.sleep(0.1)


def _ended(parent: Job, _subtasks: list[Job]) -> bool:
    return parent.status in job_service.FINAL_STATUSES


def start_worker(settings: Settings, *, stale_after_s: float) -> subprocess.Popen[bytes]:
    """A real ``driftmap -v worker`` (its start is logged) on ``settings``' data dir, quick heartbeats."""
    env = {**os.environ, "DRIFTMAP_DATA_DIR": str(settings.data_dir)}
    env.pop("DRIFTMAP_REDIS_URL", None)
    command = [sys.executable, "-m", "driftmap", "-v", "worker", "--heartbeat", "0.5"]
    command += ["--stale-after", str(stale_after_s), "--reap-every", "0.5"]
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    with (settings.data_dir / "worker.log").open("ab") as log:
        return subprocess.Popen(command, env=env, stdout=log, stderr=subprocess.STDOUT)


def _wait_started(settings: Settings, count: int) -> None:
    log = settings.data_dir / "worker.log"
    deadline = time.monotonic() + 120.0
    while not log.is_file() or log.read_text(errors="replace").count("thread(s) on") < count:
        assert time.monotonic() < deadline, log.read_text() if log.is_file() else "no worker log"
        time.sleep(0.1)


def _process(worker_id: str | None) -> str:
    return ":".join((worker_id or "").split(":")[:2])


def _counts(storage: Storage) -> tuple[int, int, int]:
    with storage.db.session() as session:
        return tuple(  # type: ignore[return-value]
            session.scalar(select(func.count()).select_from(m)) or 0 for m in (MapVersion, MapPose, Frame)
        )


@pytest.mark.slow
class TestTwoWorkers:
    def test_both_workers_take_a_drive_of_one_build(
        self, settings: Settings, storage: Storage, mini_site: Path
    ) -> None:
        import_site(storage, mini_site)
        workers = [start_worker(settings, stale_after_s=600.0) for _ in range(2)]
        try:
            _wait_started(settings, 2)
            parent, subtasks = _wait(storage, _ended, _submit(storage, settings))
        finally:
            for worker in workers:
                stop_worker(worker)
        assert parent.status == "succeeded", parent.error
        assert [s.kind for s in subtasks] == ["map.drive", "map.drive", "map.loops"]
        assert {s.status for s in subtasks} == {"succeeded"}
        assert len({_process(s.worker_id) for s in subtasks[:2]}) == 2  # one drive on each process
        assert _counts(storage)[:2] == (1, 200)

    def test_a_worker_killed_in_its_drive_leaves_it_to_the_build(
        self, settings: Settings, storage: Storage, mini_site: Path
    ) -> None:
        import_site(storage, mini_site)
        first = start_worker(settings, stale_after_s=3.0)
        second: subprocess.Popen[bytes] | None = None
        try:
            _wait_started(settings, 1)
            job_id = _submit(storage, settings)
            _wait(storage, lambda _p, subs: bool(subs) and subs[0].status == "running", job_id)
            first.send_signal(signal.SIGSTOP)  # frozen in drive 1: drive 2 waits for another worker
            second = start_worker(settings, stale_after_s=600.0)
            _, subtasks = _wait(storage, lambda _p, subs: subs[1].status == "running", job_id)
            taken_by = _process(subtasks[1].worker_id)
            second.send_signal(signal.SIGKILL)
            second.wait(timeout=30)
            first.send_signal(signal.SIGCONT)
            parent, subtasks = _wait(storage, _ended, job_id)
        finally:
            first.send_signal(signal.SIGCONT)
            stop_worker(first)
            if second is not None:
                stop_worker(second)
        assert taken_by not in (_process(subtasks[0].worker_id), "")
        assert parent.status == "succeeded", parent.error
        assert subtasks[1].status == "succeeded" and subtasks[1].attempts >= 2
        assert _process(subtasks[1].worker_id) != taken_by  # finished by the surviving worker
        versions, poses, frames = _counts(storage)
        assert (versions, poses) == (1, frames) and frames == 200
