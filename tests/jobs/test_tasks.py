"""Job tasks on a real SQLite file: huey's immediate mode runs them in-process (unit level).

The job lifecycle with a real consumer process (cancel a running job, kill a worker) is in
tests/api/test_jobs.py.
"""

from __future__ import annotations

import shutil
from datetime import timedelta
from pathlib import Path

import pytest
from sqlalchemy import delete, func, select, update

from driftmap.jobs.queue import JobQueue
from driftmap.jobs.runtime import JobContext, JobRuntime, run_job
from driftmap.jobs.tasks import map_build
from driftmap.services import jobs as job_service
from driftmap.services import sites as site_service
from driftmap.store.job_models import Job
from driftmap.store.models import Drive, Frame, Grounding, MapPose, MapVersion, utc_now
from driftmap.store.storage import Storage
from tests.jobs.mini_site import drive_folders, zip_folder
from tests.sim_site import import_site


def _submit(storage: Storage, queue: JobQueue, kind: str, args: dict[str, object], site: str | None) -> int:
    with storage.db.session() as session:
        site_id = site_service.get_site(session, site).id if site else None
        return job_service.submit(session, queue.enqueue, kind, args, site_id=site_id, created_by="test").id


def _job(storage: Storage, job_id: int) -> Job:
    with storage.db.session() as session:
        return job_service.get_job(session, job_id)


def _count(storage: Storage, model: type) -> int:
    with storage.db.session() as session:
        return session.scalar(select(func.count()).select_from(model)) or 0


class TestMapBuild:
    def test_build_job_stores_one_version_and_reports_it(
        self, storage: Storage, queue: JobQueue, mini_site: Path
    ) -> None:
        import_site(storage, mini_site)
        job_id = _submit(storage, queue, "map.build", {"preset": "fast"}, "tiny")
        job = _job(storage, job_id)
        assert job.status == "succeeded", job.error
        assert (job.progress, job.stage, job.attempts) == (1.0, "done", 1)
        assert job.result is not None and job.result["version"] == 1
        assert _count(storage, MapPose) == _count(storage, Frame) == 200
        queue.enqueue("map.build", job_id)  # a duplicate message: the job is not queued, nothing runs
        assert _count(storage, MapVersion) == 1
        assert _job(storage, job_id).attempts == 1

    def test_site_without_groundings_fails_with_the_reason(
        self, storage: Storage, queue: JobQueue, mini_site: Path
    ) -> None:
        import_site(storage, mini_site)
        with storage.db.session() as session:
            session.execute(delete(Grounding))
        job = _job(storage, _submit(storage, queue, "map.build", {"preset": "fast"}, "tiny"))
        assert job.status == "failed"
        assert "no grounding" in (job.error or "")
        assert _count(storage, MapVersion) == 0


class TestCancel:
    def test_a_cancelled_queued_job_never_starts(
        self, storage: Storage, stored_queue: JobQueue, mini_site: Path
    ) -> None:
        import_site(storage, mini_site)
        job_id = _submit(storage, stored_queue, "map.build", {"preset": "fast"}, "tiny")
        assert stored_queue.pending_job_ids() == {job_id}
        with storage.db.session() as session:
            assert job_service.cancel(session, job_id).status == "cancelled"
        message = stored_queue.huey.dequeue()
        assert message is not None
        stored_queue.huey.execute(message)
        job = _job(storage, job_id)
        assert (job.status, job.attempts, job.started_at) == ("cancelled", 0, None)
        assert _count(storage, MapVersion) == 0

    def test_a_running_job_stops_at_its_next_progress_report(
        self, storage: Storage, runtime: JobRuntime, stored_queue: JobQueue, mini_site: Path
    ) -> None:
        import_site(storage, mini_site)
        job_id = _submit(storage, stored_queue, "map.build", {"preset": "fast"}, "tiny")

        def cancelled_while_running(ctx: JobContext) -> None:
            with storage.db.session() as session:
                assert job_service.cancel(session, ctx.job.id).status == "running"
            map_build(ctx)

        run_job(runtime, cancelled_while_running, "map.build", job_id, stored_queue.enqueue)
        job = _job(storage, job_id)
        assert job.status == "cancelled" and job.finished_at is not None
        assert _count(storage, MapVersion) == 0

    def test_a_finished_job_cannot_be_cancelled(
        self, storage: Storage, queue: JobQueue, mini_site: Path
    ) -> None:
        import_site(storage, mini_site)
        job_id = _submit(storage, queue, "map.build", {"preset": "fast"}, "tiny")
        with storage.db.session() as session, pytest.raises(job_service.ConflictError):
            job_service.cancel(session, job_id)


class TestStaleJobs:
    def _running(self, storage: Storage, attempts: int, *, cancel: bool = False) -> int:
        old = utc_now() - timedelta(seconds=60)
        with storage.db.session() as session:
            job = Job(
                kind="map.build",
                args={},
                status="running",
                attempts=attempts,
                heartbeat_at=old,
                worker_id="dead-host:1:abc",
                cancel_requested_at=old if cancel else None,
            )
            session.add(job)
            session.flush()
            return job.id

    def test_stale_jobs_are_requeued_cancelled_or_failed(self, storage: Storage) -> None:
        retry = self._running(storage, 1)
        exhausted = self._running(storage, job_service.MAX_ATTEMPTS)
        cancelled = self._running(storage, 1, cancel=True)
        enqueued: list[tuple[str, int]] = []
        requeued = job_service.requeue_stale(
            storage.db, lambda kind, job_id: enqueued.append((kind, job_id)), 30.0
        )
        assert requeued == [retry] and enqueued == [("map.build", retry)]
        statuses = {j: _job(storage, j).status for j in (retry, exhausted, cancelled)}
        assert statuses == {retry: "queued", exhausted: "failed", cancelled: "cancelled"}
        assert "lost 3 times" in (_job(storage, exhausted).error or "")

    def test_a_fresh_heartbeat_is_left_alone(self, storage: Storage) -> None:
        job_id = self._running(storage, 1)
        with storage.db.session() as session:
            session.execute(update(Job).where(Job.id == job_id).values(heartbeat_at=utc_now()))
        assert job_service.requeue_stale(storage.db, lambda _k, _i: None, 30.0) == []
        assert _job(storage, job_id).status == "running"

    def test_a_requeued_job_reruns_and_the_lost_worker_cannot_finish_it(
        self, storage: Storage, queue: JobQueue, mini_site: Path
    ) -> None:
        import_site(storage, mini_site)
        job_id = self._running(storage, 1)
        with storage.db.session() as session:
            site_id = site_service.get_site(session, "tiny").id
            session.execute(
                update(Job).where(Job.id == job_id).values(site_id=site_id, args={"preset": "fast"})
            )
        assert job_service.requeue_stale(storage.db, queue.enqueue, 30.0) == [job_id]
        job = _job(storage, job_id)
        assert (job.status, job.attempts) == ("succeeded", 2)
        with storage.db.session() as session, pytest.raises(job_service.JobLost):
            job_service.finish(session, job_id, "dead-host:1:abc", "succeeded", result={})
        assert _count(storage, MapVersion) == 1


class TestDriveImport:
    def _upload(self, storage: Storage, data: bytes) -> str:
        sha, _created = storage.blobs.put(data)
        return sha

    def test_zip_import_stores_the_drive_and_drops_the_upload(
        self, storage: Storage, queue: JobQueue, mini_site: Path
    ) -> None:
        with storage.blobs.batch() as batch, storage.db.session() as session:
            site = site_service.create_site(session, "tiny")
            site_service.add_survey_map(
                session, batch, site, (mini_site / "survey.dxf").read_bytes(), "s.dxf"
            )
        folder = drive_folders(mini_site, "map")[0]
        sha = self._upload(storage, zip_folder(folder))
        args = {"upload_sha256": sha, "filename": "map.zip", "format": "zip"}
        job = _job(storage, _submit(storage, queue, "drive.import", args, "tiny"))
        assert job.status == "succeeded", job.error
        assert job.result is not None and job.result["frames"] == 100
        with storage.db.session() as session:
            drive = session.get(Drive, job.result["drive_id"])
            assert drive is not None and drive.name == folder.name and drive.frame_count == 100
            assert session.scalar(select(func.count()).select_from(Grounding)) == 1
        assert not storage.blobs.exists(sha)

    def test_a_broken_frame_fails_naming_it_and_stores_nothing(
        self, storage: Storage, queue: JobQueue, mini_site: Path, tmp_path: Path
    ) -> None:
        with storage.db.session() as session:
            site_service.create_site(session, "tiny")
        folder = tmp_path / "broken"
        shutil.copytree(drive_folders(mini_site, "map")[0], folder)
        frame = folder / "frames" / "000042.png"
        frame.write_bytes(frame.read_bytes()[:200])
        before = storage.blobs.all_names()
        sha = self._upload(storage, zip_folder(folder))
        args = {"upload_sha256": sha, "filename": "broken.zip", "format": "zip"}
        job = _job(storage, _submit(storage, queue, "drive.import", args, "tiny"))
        assert job.status == "failed"
        assert "broken.zip: broken/frames/000042.png" in (job.error or ""), job.error
        assert _count(storage, Drive) == 0 and _count(storage, Frame) == 0
        assert storage.blobs.all_names() == before


class TestLocaliseAndSimulate:
    def test_localise_a_stored_drive_against_the_built_map(
        self, storage: Storage, queue: JobQueue, mini_site: Path
    ) -> None:
        import_site(storage, mini_site, kinds=("mapping", "localisation"))
        assert _job(storage, _submit(storage, queue, "map.build", {"preset": "fast"}, "tiny")).status == (
            "succeeded"
        )
        with storage.db.session() as session:
            drive_id = session.scalar(select(Drive.id).where(Drive.kind == "localisation"))
        job = _job(storage, _submit(storage, queue, "drive.localise", {"drive_id": drive_id}, "tiny"))
        assert job.status == "succeeded", job.error
        assert job.result is not None and job.result["frames"] == 100 and job.result["map_version"] == 1
        csv = storage.blobs.get(job.result["csv_sha256"]).decode()
        header = "frame,node,x,y,score,matched,yaw,speed,odometry,x_paper"
        assert csv.splitlines()[0] == header and len(csv.splitlines()) == 101

    def test_simulate_job_creates_the_site_with_its_drives(self, storage: Storage, queue: JobQueue) -> None:
        args = {"name": "sim", "seed": 5, "size": "tiny", "max_frames_per_drive": 8}
        job = _job(storage, _submit(storage, queue, "site.simulate", args, None))
        assert job.status == "succeeded", job.error
        assert job.result is not None and job.site_id == job.result["site_id"]
        with storage.db.session() as session:
            site = site_service.get_site(session, "sim")
            counts = session.execute(
                select(func.count(), func.sum(Drive.frame_count)).where(Drive.site_id == site.id)
            ).one()
        assert counts[0] == job.result["drives"] and counts[1] == 8 * counts[0]
        again = _job(storage, _submit(storage, queue, "site.simulate", args, None))
        assert again.status == "failed" and "already exists" in (again.error or "")
