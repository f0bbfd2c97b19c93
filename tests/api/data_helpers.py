"""What the data API tests share: an app with a user of every role, job queues, a worker process, polling.

``api_users(settings)`` runs jobs in huey's immediate mode (in the request's thread, after its commit) so
router tests need no worker; tests/api/test_jobs.py starts real ``driftmap worker`` processes instead.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fastapi import FastAPI
from fastapi.testclient import TestClient

from driftmap.api.app import create_app
from driftmap.config import Settings
from driftmap.jobs.queue import JobQueue
from driftmap.jobs.runtime import JobRuntime
from driftmap.services import users as user_service
from driftmap.store.storage import Storage

PASSWORD = "correct horse battery"
ROLES = ("admin", "surveyor", "viewer")
JOB_DEADLINE_S = 240.0  # a FAST build of the mini site takes seconds; this only bounds a hang


@dataclass
class ApiUsers:
    """A running app (TestClient) with a logged-in user of every role."""

    app: FastAPI
    client: TestClient
    tokens: dict[str, str]

    @property
    def storage(self) -> Storage:
        storage: Storage = self.app.state.storage
        return storage

    def auth(self, role: str) -> dict[str, str]:
        return {"Authorization": f"Bearer {self.tokens[role]}"}

    def get(self, url: str, role: str = "viewer", **kwargs: Any) -> Any:
        response = self.client.get(url, headers=self.auth(role), **kwargs)
        assert response.status_code == 200, response.text
        return response.json()

    def job(self, job_id: int) -> dict[str, Any]:
        job: dict[str, Any] = self.get(f"/api/jobs/{job_id}")
        return job

    def wait_job(
        self,
        job_id: int,
        until: Callable[[dict[str, Any]], bool] | None = None,
        deadline_s: float = JOB_DEADLINE_S,
    ) -> dict[str, Any]:
        """Poll the job until ``until(job)`` (default: a final status) or fail at the deadline."""
        done = until or (lambda j: j["status"] in ("succeeded", "failed", "cancelled"))
        end = time.monotonic() + deadline_s
        while True:
            job = self.job(job_id)
            if done(job):
                return job
            assert time.monotonic() < end, (
                f"job {job_id} still {job['status']} ({job['stage']}) at the deadline"
            )
            time.sleep(0.1)


def api_users(settings: Settings, *, immediate: bool = True) -> ApiUsers:
    """An app on ``settings``; jobs run in-process (immediate) or wait for a worker process."""
    app = create_app(settings)
    storage: Storage = app.state.storage
    if immediate:
        runtime = JobRuntime(settings=settings, storage=storage, heartbeat_s=0.5, progress_interval_s=0.2)
        app.state.job_queue = JobQueue(settings, immediate=True, runtime=runtime)
    with storage.db.session() as session:
        for role in ROLES:
            user_service.create_user(session, role, PASSWORD, role)
    client = TestClient(app)
    tokens = {}
    for role in ROLES:
        response = client.post("/api/auth/login", json={"username": role, "password": PASSWORD})
        assert response.status_code == 200, response.text
        tokens[role] = response.json()["access_token"]
    client.cookies.clear()  # each request states its user explicitly
    return ApiUsers(app, client, tokens)


def upload_zip(users: ApiUsers, site_id: int, name: str, data: bytes, role: str = "surveyor") -> Any:
    """POST a drive zip; returns the response."""
    return users.client.post(
        f"/api/sites/{site_id}/drives/zip",
        files={"file": (name, data, "application/zip")},
        headers=users.auth(role),
    )


def create_site_with_survey(users: ApiUsers, site_dir: Path, name: str = "mini") -> int:
    """A site made through the API with the simulated site's survey.dxf; returns its id."""
    response = users.client.post("/api/sites", json={"name": name}, headers=users.auth("admin"))
    assert response.status_code == 201, response.text
    site_id: int = response.json()["id"]
    dxf = (site_dir / "survey.dxf").read_bytes()
    response = users.client.post(
        f"/api/sites/{site_id}/survey",
        files={"file": ("survey.dxf", dxf, "application/dxf")},
        headers=users.auth("admin"),
    )
    assert response.status_code == 201, response.text
    return site_id


def start_worker(settings: Settings, *, stale_after_s: float = 3.0) -> subprocess.Popen[bytes]:
    """A real ``driftmap worker`` process on ``settings``' data dir (and Redis queue if set), quick heartbeats."""
    env = {**os.environ, "DRIFTMAP_DATA_DIR": str(settings.data_dir)}
    env.pop("DRIFTMAP_REDIS_URL", None)
    if settings.redis_url:
        env["DRIFTMAP_REDIS_URL"] = settings.redis_url
    command = [sys.executable, "-m", "driftmap", "worker", "--heartbeat", "0.5"]
    command += ["--stale-after", str(stale_after_s), "--reap-every", "0.5"]
    settings.data_dir.mkdir(parents=True, exist_ok=True)
    with (settings.data_dir / "worker.log").open("ab") as log:  # the child keeps its own handle
        return subprocess.Popen(command, env=env, stdout=log, stderr=subprocess.STDOUT)


def stop_worker(process: subprocess.Popen[bytes]) -> None:
    """Stop a worker started by :func:`start_worker` (SIGTERM, then SIGKILL)."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
