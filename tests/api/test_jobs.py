"""The job lifecycle with real ``driftmap worker`` processes on the embedded SQLite queue.

Upload drives as zips, build a map through a job and read it back; cancel a queued and a running job; kill a
worker with SIGKILL in the middle of a map build and check that another worker finishes it exactly once.
"""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import get_args

import httpx
import pytest
from sqlalchemy import func, select

from driftmap.api.jobs import JobKind, JobStatus
from driftmap.config import Settings
from driftmap.services.jobs import QUEUE_KINDS
from driftmap.store.job_models import JOB_STATUSES
from driftmap.store.models import Frame, MapPose, MapVersion
from driftmap.store.storage import Storage
from tests.api.data_helpers import (
    ApiUsers,
    api_users,
    create_site_with_survey,
    start_worker,
    stop_worker,
    upload_zip,
)
from tests.jobs.mini_site import drive_folders, zip_folder
from tests.redis_server import running_redis
from tests.sim_site import import_site

pytestmark = pytest.mark.slow  # real driftmap worker processes


@pytest.fixture
def users(settings: Settings) -> Iterator[ApiUsers]:
    """Unlike the shared ``users``: jobs wait in the data dir's queue for a ``driftmap worker`` process."""
    made = api_users(settings, immediate=False)
    yield made
    made.client.close()


@pytest.fixture
def site_id(users: ApiUsers, mini_site: Path) -> int:
    """The mini site's mapping drives imported directly (the upload path is tested on its own)."""
    import_site(users.storage, mini_site, name="tiny")
    return int(users.get("/api/sites")["items"][0]["id"])


def _build(users: ApiUsers, site_id: int) -> int:
    response = users.client.post(
        f"/api/sites/{site_id}/maps", json={"preset": "fast"}, headers=users.auth("surveyor")
    )
    assert response.status_code == 202, response.text
    assert response.json()["status"] == "queued"
    assert response.headers["location"] == f"/api/jobs/{response.json()['id']}"
    return int(response.json()["id"])


def _counts(storage: Storage) -> tuple[int, int, int]:
    with storage.db.session() as session:
        versions = session.scalar(select(func.count()).select_from(MapVersion)) or 0
        poses = session.scalar(select(func.count()).select_from(MapPose)) or 0
        frames = session.scalar(select(func.count()).select_from(Frame)) or 0
    return versions, poses, frames


def _in_odometry(job: dict[str, object]) -> bool:
    return job["status"] == "running" and "odometry" in str(job["stage"]) and float(str(job["progress"])) > 0


class TestLifecycle:
    def test_upload_build_and_read_back_through_a_worker(
        self, users: ApiUsers, settings: Settings, mini_site: Path
    ) -> None:
        site_id = create_site_with_survey(users, mini_site)
        worker = start_worker(settings)
        try:
            imports = []
            for folder in drive_folders(mini_site, "map"):
                response = upload_zip(users, site_id, f"{folder.name}.zip", zip_folder(folder))
                assert response.status_code == 202, response.text
                imports.append(response.json()["id"])
            for job_id in imports:
                job = users.wait_job(job_id)
                assert job["status"] == "succeeded", job["error"]
                assert job["result"]["frames"] == 100 and job["attempts"] == 1
            build = users.wait_job(_build(users, site_id))
        finally:
            stop_worker(worker)
        assert build["status"] == "succeeded", build["error"]
        assert (build["progress"], build["stage"]) == (1.0, "done")
        version = build["result"]["version"]
        detail = users.get(f"/api/sites/{site_id}/maps/{version}")
        assert detail["poses"] == 200 and detail["residuals"] == 2 and detail["nodes"] >= 5
        poses = users.get(f"/api/sites/{site_id}/maps/{version}/poses")
        assert poses["total"] == len(poses["x_m"]) == 200
        residuals = users.get(f"/api/sites/{site_id}/maps/{version}/residuals")
        assert len(residuals) == 2 and all(r["distance_m"] < 2.0 for r in residuals)
        listed = users.get("/api/jobs", params={"site_id": site_id, "kind": "drive.import"})
        assert listed["total"] == 2 and {j["status"] for j in listed["items"]} == {"succeeded"}
        top_level = users.get("/api/jobs", params={"site_id": site_id})["items"]
        assert {j["kind"] for j in top_level} == {"drive.import", "map.build"}
        assert all(j["parent_id"] is None for j in top_level)
        subtasks = users.get("/api/jobs", params={"parent_id": build["id"]})["items"]
        kinds = [j["kind"] for j in sorted(subtasks, key=lambda j: j["id"])]  # per drive, then loop blocks
        assert kinds[:2] == ["map.drive", "map.drive"] and kinds[2:] == ["map.loops"] * (len(kinds) - 2)
        assert len(kinds) >= 3
        assert {(j["parent_id"], j["status"]) for j in subtasks} == {(build["id"], "succeeded")}

    def test_progress_stream_ends_with_the_final_state(
        self, users: ApiUsers, settings: Settings, site_id: int
    ) -> None:
        job_id = _build(users, site_id)
        worker = start_worker(settings)
        try:
            events = []
            with users.client.stream(
                "GET", f"/api/jobs/{job_id}/events", headers=users.auth("viewer")
            ) as stream:
                assert stream.headers["content-type"].startswith("text/event-stream")
                for line in stream.iter_lines():
                    if line.startswith("data: "):
                        events.append(json.loads(line.removeprefix("data: ")))
        finally:
            stop_worker(worker)
        assert events[0]["status"] in ("queued", "running")
        assert events[-1]["status"] == "succeeded"
        progress = [e["progress"] for e in events if e["status"] == "running"]
        assert len(events) >= 3 and progress and max(progress) > 0


class TestCancel:
    def test_a_queued_job_cancelled_before_any_worker_never_runs(
        self, users: ApiUsers, settings: Settings, site_id: int
    ) -> None:
        job_id = _build(users, site_id)
        response = users.client.post(f"/api/jobs/{job_id}/cancel", headers=users.auth("surveyor"))
        assert response.status_code == 200 and response.json()["status"] == "cancelled"
        later = _build(users, site_id)  # queued behind it: once this ran, the worker has seen the first one
        worker = start_worker(settings)
        try:
            assert users.wait_job(later)["status"] == "succeeded"
        finally:
            stop_worker(worker)
        cancelled = users.job(job_id)
        assert (cancelled["status"], cancelled["attempts"], cancelled["started_at"]) == ("cancelled", 0, None)
        assert _counts(users.storage)[0] == 1

    def test_a_running_job_stops_at_its_next_progress_report(
        self, users: ApiUsers, settings: Settings, site_id: int
    ) -> None:
        worker = start_worker(settings)
        try:
            job_id = _build(users, site_id)
            users.wait_job(job_id, _in_odometry)
            response = users.client.post(f"/api/jobs/{job_id}/cancel", headers=users.auth("surveyor"))
            assert response.status_code == 200 and response.json()["cancel_requested_at"] is not None
            job = users.wait_job(job_id)
        finally:
            stop_worker(worker)
        assert job["status"] == "cancelled" and job["result"] is None
        assert _counts(users.storage)[:2] == (0, 0)
        again = users.client.post(f"/api/jobs/{job_id}/cancel", headers=users.auth("surveyor"))
        assert again.status_code == 200 and again.json()["status"] == "cancelled"


class TestWorkerKilled:
    def test_a_build_whose_worker_is_killed_is_finished_once_by_another(
        self, users: ApiUsers, settings: Settings, site_id: int
    ) -> None:
        first = start_worker(settings)
        try:
            job_id = _build(users, site_id)
            running = users.wait_job(job_id, _in_odometry)
            first.send_signal(signal.SIGKILL)
            first.wait(timeout=30)
        finally:
            stop_worker(first)
        assert running["attempts"] == 1
        assert users.job(job_id)["status"] == "running"  # nobody knows yet
        second = start_worker(settings)
        try:
            job = users.wait_job(job_id)
        finally:
            stop_worker(second)
        assert job["status"] == "succeeded", job["error"]
        assert job["attempts"] == 2 and job["worker_id"] != running["worker_id"]
        versions, poses, frames = _counts(users.storage)
        assert (versions, poses) == (1, frames) and frames == 200
        assert job["result"]["version"] == 1


class TestWorkerStopped:
    def test_sigterm_puts_the_running_job_back_for_the_next_worker(
        self, users: ApiUsers, settings: Settings, site_id: int
    ) -> None:
        first = start_worker(settings, stale_after_s=600.0)  # only the shutdown hand-back can save the job
        try:
            job_id = _build(users, site_id)
            users.wait_job(job_id, _in_odometry)
            first.send_signal(signal.SIGTERM)
            first.wait(timeout=60)
        finally:
            stop_worker(first)
        handed_back = users.job(job_id)
        assert handed_back["status"] == "queued" and handed_back["worker_id"] is None
        second = start_worker(settings, stale_after_s=600.0)
        try:
            job = users.wait_job(job_id)
        finally:
            stop_worker(second)
        assert job["status"] == "succeeded" and job["attempts"] == 2
        assert _counts(users.storage)[:2] == (1, 200)


@pytest.fixture
def redis_url(tmp_path: Path) -> Iterator[str]:
    """A private redis-server for this test (skipped without redis-server)."""
    with running_redis(tmp_path) as url:
        yield url


class TestSharedQueue:
    @pytest.mark.parametrize("backend", ["sqlite", "redis"])
    def test_two_workers_share_one_queue(
        self, backend: str, request: pytest.FixtureRequest, tmp_path: Path, mini_site: Path
    ) -> None:
        settings = Settings(data_dir=tmp_path / "data")
        if backend == "redis":
            settings = settings.model_copy(update={"redis_url": request.getfixturevalue("redis_url")})
        shared = api_users(settings, immediate=False)
        for name in ("tiny", "tiny-b"):  # one build per site: a site builds one version at a time
            import_site(shared.storage, mini_site, name=name)
        site_a, site_b = sorted(int(s["id"]) for s in shared.get("/api/sites")["items"])
        first = start_worker(settings, stale_after_s=600.0)
        second: subprocess.Popen[bytes] | None = None
        try:
            job_a = _build(shared, site_a)
            shared.wait_job(job_a, _in_odometry)
            first.send_signal(signal.SIGSTOP)  # frozen mid-job: only another worker can run the next one
            second = start_worker(settings, stale_after_s=600.0)
            job_b = shared.wait_job(_build(shared, site_b))
            first.send_signal(signal.SIGCONT)
            job_a_done = shared.wait_job(job_a)
        finally:
            first.send_signal(signal.SIGCONT)
            stop_worker(first)
            if second is not None:
                stop_worker(second)
            shared.client.close()
        assert (job_a_done["status"], job_b["status"]) == ("succeeded", "succeeded")
        pids = [int(str(j["worker_id"]).split(":")[1]) for j in (job_a_done, job_b)]
        assert pids == [first.pid, second.pid]
        assert [j["result"]["version"] for j in (job_a_done, job_b)] == [1, 1]


class TestServe:
    def test_driftmap_serve_imports_and_builds_over_real_http(self, tmp_path: Path, mini_site: Path) -> None:
        """`driftmap serve` (uvicorn and the worker process it starts): the jobs only run if that worker does."""
        env = {**os.environ, "DRIFTMAP_DATA_DIR": str(tmp_path / "data")}
        env.pop("DRIFTMAP_REDIS_URL", None)
        command = [sys.executable, "-m", "driftmap"]
        subprocess.run(
            [*command, "user", "add", "boss", "--role", "admin", "--password-stdin"],
            input=b"long enough password\n",
            env=env,
            check=True,
            capture_output=True,
        )
        with socket.socket() as probe:
            probe.bind(("127.0.0.1", 0))
            port = probe.getsockname()[1]
        log = (tmp_path / "serve.log").open("wb")
        server = subprocess.Popen([*command, "serve", "--port", str(port)], env=env, stdout=log, stderr=log)
        base = f"http://127.0.0.1:{port}/api"
        try:
            with httpx.Client(base_url=base, timeout=60) as http:
                deadline = time.monotonic() + 120
                while True:
                    try:
                        if http.get("/health").status_code == 200:
                            break
                    except httpx.TransportError:
                        pass
                    assert time.monotonic() < deadline, (tmp_path / "serve.log").read_text()
                    time.sleep(0.2)
                token = http.post(
                    "/auth/login", json={"username": "boss", "password": "long enough password"}
                )
                http.headers["Authorization"] = f"Bearer {token.json()['access_token']}"
                http.cookies.clear()
                site_id = http.post("/sites", json={"name": "mini"}).json()["id"]
                survey = (mini_site / "survey.dxf").read_bytes()
                assert (
                    http.post(f"/sites/{site_id}/survey", files={"file": ("survey.dxf", survey)}).status_code
                    == 201
                )
                jobs = [
                    http.post(
                        f"/sites/{site_id}/drives/zip", files={"file": (f"{f.name}.zip", zip_folder(f))}
                    ).json()["id"]
                    for f in drive_folders(mini_site, "map")
                ]
                for job_id in jobs:
                    assert _wait_http(http, job_id)["status"] == "succeeded"
                build_id = http.post(f"/sites/{site_id}/maps", json={"preset": "fast"}).json()["id"]
                events = []
                with http.stream("GET", f"/jobs/{build_id}/events") as stream:
                    for line in stream.iter_lines():
                        if line.startswith("data: "):
                            events.append(json.loads(line.removeprefix("data: ")))
                assert events[-1]["status"] == "succeeded", events[-1]["error"]
                residuals = http.get(f"/sites/{site_id}/maps/1/residuals").json()
                assert len(residuals) == 2
        finally:
            server.terminate()
            server.wait(timeout=60)
            log.close()


def _wait_http(http: httpx.Client, job_id: int) -> dict[str, object]:
    """Poll a job over HTTP until it ends (or fail at the deadline)."""
    deadline = time.monotonic() + 240
    while (job := http.get(f"/jobs/{job_id}").json())["status"] in ("queued", "running"):
        assert time.monotonic() < deadline, job
        time.sleep(0.1)
    return dict(job)


class TestListFilters:
    def test_filters_are_the_stored_kinds_and_statuses(self, users: ApiUsers) -> None:
        assert set(get_args(JobKind)) == set(QUEUE_KINDS) and set(get_args(JobStatus)) == set(JOB_STATUSES)
        response = users.client.get("/api/jobs", params={"status": "done"}, headers=users.auth("viewer"))
        assert response.status_code == 422
        assert users.get("/api/jobs", params={"status": "queued", "kind": "map.build"})["total"] == 0
