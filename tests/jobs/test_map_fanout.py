"""The fanned-out map build (``map.build`` + ``map.drive`` subtasks) on a real SQLite file and SqliteHuey queue.

Runs the jobs in this process (huey's immediate mode, or ``run_job`` on a queue with no consumer); the build
on two real worker processes is bench/bench_map_workers.py.
"""

from __future__ import annotations

import itertools
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from sqlalchemy import func, select

from driftmap.core.mapping import prepare as map_prepare
from driftmap.core.mapping.pipeline import MAP_PRESETS, MAPPING_FAST, build_map
from driftmap.core.topomap import database as place_database
from driftmap.jobs import map_tasks
from driftmap.jobs.map_tasks import map_build
from driftmap.jobs.queue import JobQueue
from driftmap.jobs.runtime import JobContext, JobRuntime, process_worker_prefix, run_job
from driftmap.services import jobs as job_service
from driftmap.services import loop_searches
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.store.job_models import Job
from driftmap.store.models import Frame, MapLoopSearch, MapNode, MapPiece, MapPose, MapVersion
from driftmap.store.storage import Storage
from tests.sim_site import import_site


def _submit(storage: Storage, queue: JobQueue) -> int:
    with storage.db.session() as session:
        site_id = site_service.get_site(session, "tiny").id
        job = job_service.submit(
            session, queue.enqueue, "map.build", {"preset": "fast"}, site_id=site_id, created_by="test"
        )
        return job.id


def _jobs(storage: Storage, parent_id: int) -> tuple[Job, list[Job]]:
    with storage.db.session() as session:
        return job_service.get_job(session, parent_id), job_service.children(session, parent_id)


class TestFanOut:
    def test_the_build_equals_the_one_process_build_bit_for_bit(
        self, storage: Storage, queue: JobQueue, mini_site: Path, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        # Dense keyframes in blocks of 8, four blocks to a map.loops subtask: several on this small site; and
        # drive segments of 64 frames (statistics chunks of 32): two map.drive subtasks per 100-frame drive.
        for module in (place_database, map_prepare):
            monkeypatch.setattr(module, "STATS_CHUNK", 32)
        params = replace(
            MAPPING_FAST,
            keyframe_spacing_m=0.25,
            loops=replace(MAPPING_FAST.loops, coarse_block=8),
            segment_frames=64,
        )
        monkeypatch.setitem(MAP_PRESETS, "fast", params)
        monkeypatch.setattr(loop_searches, "QUERIES_PER_BLOCK", 32)
        import_site(storage, mini_site)
        parent, subtasks = _jobs(storage, _submit(storage, queue))
        assert parent.status == "succeeded", parent.error
        n_blocks = sum(j.kind == "map.loops" for j in subtasks)
        assert [j.kind for j in subtasks] == ["map.drive"] * 4 + ["map.loops"] * n_blocks
        spans = [(j.args["first"], j.args["stop"]) for j in subtasks[:4]]
        assert spans == [(0, 64), (64, 100)] * 2
        assert n_blocks >= 3
        blocks = [(j.args["q0"], j.args["q1"]) for j in subtasks[4:]]
        assert blocks[0][0] == 0 and all(a[1] == b[0] for a, b in itertools.pairwise(blocks))
        assert all(j.status == "succeeded" and j.site_id == parent.site_id for j in subtasks)
        with storage.db.session() as session:
            loaded = map_service.load_site_drives(
                session, storage.blobs, site_service.get_site(session, "tiny")
            )
            stored = np.array(
                session.execute(
                    select(MapPose.x_m, MapPose.y_m, MapPose.yaw_rad).order_by(MapPose.frame_id)
                ).all()
            )
            centres = np.array(session.execute(select(MapNode.x_m, MapNode.y_m).order_by(MapNode.node)).all())
            version = session.scalars(select(MapVersion)).one()
        alone = build_map(loaded.inputs, params)
        np.testing.assert_array_equal(stored, np.concatenate(alone.wTi))
        np.testing.assert_array_equal(centres, alone.topomap.centres_m)
        figures = {k: v for k, v in alone.stats.items() if not k.endswith("_s")}
        assert {k: version.stats[k] for k in figures} == pytest.approx(figures, rel=0, abs=0)
        with storage.db.session() as session:
            kept = set(session.scalars(select(MapPiece.blob_sha256)))
            search = session.scalars(select(MapLoopSearch)).one()
        assert [tuple(b[:2]) for b in search.blocks] == blocks  # the site's kept search: the blocks as scored
        for job in (
            subtasks
        ):  # once the version was stored: the pieces and the blocks' scores kept, the plan dropped
            shas = [v for d in (job.args, job.result or {}) for k, v in d.items() if k.endswith("_sha256")]
            if job.kind == "map.drive":
                assert shas and all(sha in kept and storage.blobs.exists(sha) for sha in shas)
            else:
                assert not storage.blobs.exists(job.args["search_sha256"])
                assert job.result is not None and storage.blobs.exists(job.result["scores_sha256"])
                assert [job.args["q0"], job.args["q1"], job.result["scores_sha256"]] in search.blocks
        assert (version.stats["segments_reused"], version.stats["segments_prepared"]) == (0, 4)

    def test_one_worker_alone_runs_every_subtask_itself(
        self, storage: Storage, runtime: JobRuntime, stored_queue: JobQueue, mini_site: Path
    ) -> None:
        import_site(storage, mini_site)
        parent_id = _submit(storage, stored_queue)
        run_job(runtime, map_build, "map.build", parent_id, stored_queue.enqueue)
        parent, subtasks = _jobs(storage, parent_id)
        assert parent.status == "succeeded", parent.error
        assert [j.kind for j in subtasks] == ["map.drive", "map.drive", "map.loops"]
        for job in subtasks:
            assert (job.status, job.attempts) == ("succeeded", 1)
            assert (job.worker_id or "").startswith(process_worker_prefix())
        assert stored_queue.pending_job_ids() >= {j.id for j in subtasks}  # their messages wait, unneeded
        message = stored_queue.huey.dequeue()
        assert message is not None
        stored_queue.huey.execute(message)  # a late worker takes a message: the subtask is not queued
        with storage.db.session() as session:
            assert session.scalar(select(func.count()).select_from(MapVersion)) == 1

    def test_a_rerun_after_the_build_died_reuses_the_finished_subtasks(
        self,
        storage: Storage,
        runtime: JobRuntime,
        stored_queue: JobQueue,
        mini_site: Path,
        monkeypatch: pytest.MonkeyPatch,
    ) -> None:
        import_site(storage, mini_site)
        parent_id = _submit(storage, stored_queue)
        real_store = map_service.store_map_version

        def dies(*args: object, **kwargs: object) -> None:
            raise RuntimeError("the worker died while storing")

        monkeypatch.setattr(map_service, "store_map_version", dies)
        with pytest.raises(RuntimeError):
            run_job(runtime, map_build, "map.build", parent_id, stored_queue.enqueue)
        parent, subtasks = _jobs(storage, parent_id)
        assert parent.status == "queued" and [j.status for j in subtasks] == ["succeeded"] * 3
        monkeypatch.setattr(map_service, "store_map_version", real_store)
        run_job(runtime, map_build, "map.build", parent_id, stored_queue.enqueue)
        parent, again = _jobs(storage, parent_id)
        assert (parent.status, parent.attempts) == ("succeeded", 2), parent.error
        assert [j.id for j in again] == [j.id for j in subtasks]
        assert [j.attempts for j in again] == [1, 1, 1]  # the drives and the loop search not run twice
        with storage.db.session() as session:
            assert session.scalar(select(func.count()).select_from(MapPose)) == session.scalar(
                select(func.count()).select_from(Frame)
            )

    def test_a_failed_subtask_fails_the_build_naming_it(
        self, storage: Storage, queue: JobQueue, mini_site: Path
    ) -> None:
        import_site(storage, mini_site)
        with storage.db.session() as session:
            sha = session.scalars(select(Frame.blob_sha256).order_by(Frame.id.desc())).first()
        assert sha is not None
        storage.blobs.path_of(sha).write_bytes(b"not a png")
        parent, subtasks = _jobs(storage, _submit(storage, queue))
        assert parent.status == "failed"
        assert f"map.drive subtask {subtasks[-1].id} failed" in (parent.error or ""), parent.error
        assert subtasks[-1].status == "failed"
        with storage.db.session() as session:
            assert session.scalar(select(func.count()).select_from(MapVersion)) == 0


class TestCancel:
    def test_cancelling_a_build_cancels_its_subtasks(self, storage: Storage) -> None:
        with storage.db.session() as session:
            parent = Job(kind="map.build", args={}, status="running", worker_id="w:1:a")
            session.add(parent)
            session.flush()
            queued = Job(kind="map.drive", args={}, status="queued", parent_id=parent.id)
            running = Job(kind="map.drive", args={}, status="running", parent_id=parent.id, worker_id="w:2:b")
            done = Job(kind="map.drive", args={}, status="succeeded", parent_id=parent.id)
            other = Job(kind="map.drive", args={}, status="queued")
            session.add_all([queued, running, done, other])
            session.flush()
            ids = (parent.id, queued.id, running.id, done.id, other.id)
        with storage.db.session() as session:
            job_service.cancel(session, ids[0])
        with storage.db.session() as session:
            rows = {j.id: j for j in session.scalars(select(Job))}
        assert rows[ids[0]].cancel_requested_at is not None
        assert rows[ids[1]].status == "cancelled"
        assert rows[ids[2]].status == "running" and rows[ids[2]].cancel_requested_at is not None
        assert rows[ids[3]].status == "succeeded" and rows[ids[4]].status == "queued"

    def test_a_cancelled_subtask_cancels_the_build(
        self,
        storage: Storage,
        runtime: JobRuntime,
        stored_queue: JobQueue,
        mini_site: Path,
        monkeypatch: pytest.MonkeyPatch,
    ) -> None:
        import_site(storage, mini_site)
        parent_id = _submit(storage, stored_queue)
        real = map_tasks._segment_subtasks

        def submitted_then_one_cancelled(ctx: JobContext, *args: Any) -> list[int]:
            ids = real(ctx, *args)
            with storage.db.session() as session:
                job_service.cancel(session, ids[1])
            return ids

        monkeypatch.setattr(map_tasks, "_segment_subtasks", submitted_then_one_cancelled)
        run_job(runtime, map_build, "map.build", parent_id, stored_queue.enqueue)
        parent, subtasks = _jobs(storage, parent_id)
        assert parent.status == "cancelled"
        assert subtasks[1].status == "cancelled" and subtasks[0].status in ("cancelled", "succeeded")
        with storage.db.session() as session:
            assert session.scalar(select(func.count()).select_from(MapVersion)) == 0
