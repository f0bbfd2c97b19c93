"""The worker's bookkeeping on a real SQLite file and a real SqliteHuey queue (no consumer running)."""

from __future__ import annotations

import os
import time
from datetime import timedelta

from huey import RedisHuey, SqliteHuey
from sqlalchemy import select

from driftmap.config import Settings
from driftmap.jobs.queue import JobQueue, make_huey
from driftmap.jobs.runtime import process_worker_prefix
from driftmap.jobs.worker import Reaper, WorkerTimings, enqueue_orphans, release_own_jobs, sweep_scratch
from driftmap.services import jobs as job_service
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.store.access_models import VehiclePosition
from driftmap.store.job_models import Job
from driftmap.store.models import utc_now
from driftmap.store.storage import Storage


def _row(storage: Storage, status: str, worker_id: str | None = None) -> int:
    with storage.db.session() as session:
        job = Job(kind="map.build", args={}, status=status, worker_id=worker_id, heartbeat_at=utc_now())
        session.add(job)
        session.flush()
        return job.id


class TestQueueChoice:
    def test_sqlite_queue_lives_in_the_data_dir(self, settings: Settings) -> None:
        huey = make_huey(settings)
        assert isinstance(huey, SqliteHuey)
        JobQueue(settings).enqueue("map.build", 1)
        assert (settings.data_dir / "queue.db").is_file()

    def test_redis_url_selects_the_redis_queue(self, settings: Settings) -> None:
        redis_settings = settings.model_copy(update={"redis_url": "redis://127.0.0.1:1/0"})
        assert isinstance(make_huey(redis_settings), RedisHuey)


class TestOrphans:
    def test_queued_jobs_missing_from_the_queue_are_enqueued_once(
        self, settings: Settings, storage: Storage
    ) -> None:
        queue = JobQueue(settings)
        with storage.db.session() as session:
            submitted = job_service.submit(session, queue.enqueue, "map.build", {}).id
        lost = _row(storage, "queued")  # committed, but its enqueue never happened
        _row(storage, "succeeded")
        assert queue.pending_job_ids() == {submitted}
        assert enqueue_orphans(queue, storage) == [lost]
        assert queue.pending_job_ids() == {submitted, lost}
        assert enqueue_orphans(queue, storage) == []

    def test_a_rolled_back_submit_enqueues_nothing(self, settings: Settings, storage: Storage) -> None:
        queue = JobQueue(settings)
        try:
            with storage.db.session() as session:
                job_service.submit(session, queue.enqueue, "map.build", {})
                raise RuntimeError("the request failed after the submit")
        except RuntimeError:
            pass
        assert queue.pending_job_ids() == set()
        with storage.db.session() as session:
            assert session.scalars(select(Job)).all() == []


class TestShutdown:
    def test_only_this_process_jobs_are_handed_back(self, settings: Settings, storage: Storage) -> None:
        queue = JobQueue(settings)
        mine = _row(storage, "running", f"{process_worker_prefix()}abcd1234")
        other = _row(storage, "running", "elsewhere:1:abcd1234")
        assert release_own_jobs(queue, storage) == [mine]
        with storage.db.session() as session:
            statuses = {j.id: j.status for j in session.scalars(select(Job))}
        assert statuses == {mine: "queued", other: "running"}
        assert queue.pending_job_ids() == {mine}


class TestScratch:
    def test_folders_of_dead_jobs_and_old_uploads_are_swept(
        self, settings: Settings, storage: Storage
    ) -> None:
        running = _row(storage, "running", "elsewhere:1:abcd1234")
        finished = _row(storage, "failed")
        root = settings.data_dir / "tmp"
        keep = [root / f"job-{running}-abc", root / "upload-fresh"]
        drop = [root / f"job-{finished}-abc", root / "upload-old"]
        for folder in keep + drop:
            (folder / "inner").mkdir(parents=True)
        old = time.time() - 7 * 3600
        os.utime(root / "upload-old", (old, old))
        assert sweep_scratch(settings, storage) == 2
        assert [f.exists() for f in keep + drop] == [True, True, False, False]


def test_the_reaper_applies_the_history_retention(settings: Settings, storage: Storage) -> None:
    """A worker's reaper deletes positions past the retention on its first round."""
    with storage.db.session() as session:
        site = site_service.create_site(session, "north")
        vehicle, _token = vehicle_service.create_vehicle(session, "loader", site.id)
        old = utc_now() - timedelta(days=settings.history_keep_days + 1)
        for k in range(5):
            session.add(
                VehiclePosition(
                    vehicle_id=vehicle.id, t_s=float(k), node=1, x_m=0.0, y_m=0.0, confidence=1.0,
                    matched=True, lost=False, received_at=old + timedelta(seconds=k),
                )
            )  # fmt: skip
    queue = JobQueue(settings)
    reaper = Reaper(queue, storage, WorkerTimings(reap_every_s=0.05), settings)
    reaper.start()
    try:
        deadline = time.monotonic() + 10.0
        while time.monotonic() < deadline:
            with storage.db.session() as session:
                if not session.scalars(select(VehiclePosition.id)).all():
                    break
            time.sleep(0.05)
    finally:
        reaper.stop()
    with storage.db.session() as session:
        assert session.scalars(select(VehiclePosition.id)).all() == []
