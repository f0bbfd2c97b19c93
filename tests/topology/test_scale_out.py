"""The scale-out topology of docker-compose.yml, natively: PostgreSQL, Redis, two APIs and two workers.

A private PostgreSQL and redis-server on loopback; ``driftmap db upgrade`` migrates the empty database once;
two ``driftmap serve`` API processes and two ``driftmap worker`` processes share it, the Redis queue and live
hub, and one data directory (the blob store, a shared volume in compose). The scenario: import the tiny
simulated site through both APIs, build its map on the workers, stream the frames of two vehicles into both
APIs alternately while a watcher listens on each API, then kill a worker in the middle of a second map build.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
import uuid
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import httpx
import psycopg
import pytest
from websockets.sync.client import connect

from tests.api.access_helpers import recorded_frames
from tests.jobs.mini_site import drive_folders, zip_folder
from tests.postgres_server import PostgresServer
from tests.processes import driftmap_env, free_port, stop, wait_healthy
from tests.redis_server import running_redis

pytestmark = [pytest.mark.topology, pytest.mark.slow]

PASSWORD = "topology-admin-password"
START_DEADLINE_S = 120.0
JOB_DEADLINE_S = 600.0
FRAMES_PER_VEHICLE = 30
DRIVER = [sys.executable, "-m", "driftmap"]


@dataclass
class Topology:
    """The running processes and how to reach them."""

    apis: list[str]
    """Base URLs of the two API processes."""
    workers: dict[int, subprocess.Popen[bytes]]
    """Worker processes by pid."""
    database_url: str
    env: dict[str, str]
    logs: Path
    headers: dict[str, str] = field(default_factory=dict)

    def call(self, api: int, method: str, path: str, **kwargs: Any) -> httpx.Response:
        return httpx.request(
            method, f"{self.apis[api]}/api{path}", headers=self.headers, timeout=120.0, **kwargs
        )

    def rows(self, query: str) -> list[tuple[Any, ...]]:
        """Rows of a read-only SQL query on the shared PostgreSQL database."""
        url = self.database_url.replace("postgresql+psycopg://", "postgresql://")
        with psycopg.connect(url) as connection:
            return list(connection.execute(query).fetchall())

    def log_tail(self) -> str:
        return "\n".join(f"== {p.name}\n{p.read_text()[-3000:]}" for p in sorted(self.logs.glob("*.log")))


def _start(command: list[str], env: dict[str, str], log: Path) -> subprocess.Popen[bytes]:
    with log.open("wb") as sink:
        return subprocess.Popen(command, env=env, stdout=sink, stderr=subprocess.STDOUT)


@pytest.fixture(scope="module")
def topology(tmp_path_factory: pytest.TempPathFactory, postgres_server: PostgresServer) -> Iterator[Topology]:
    work = tmp_path_factory.mktemp("topology")
    logs = work / "logs"
    logs.mkdir()
    with running_redis(work) as redis_url:
        database_url = postgres_server.create_database(f"topology_{uuid.uuid4().hex[:8]}")  # empty
        env = driftmap_env(work / "data", database_url, redis_url=redis_url)
        upgraded = subprocess.run([*DRIVER, "db", "upgrade"], env=env, capture_output=True, check=False)
        assert upgraded.returncode == 0, upgraded.stderr.decode()
        added = subprocess.run(
            [*DRIVER, "user", "add", "admin", "--role", "admin", "--password-stdin"],
            input=f"{PASSWORD}\n".encode(),
            env=env,
            capture_output=True,
            check=False,
        )
        assert added.returncode == 0, added.stderr.decode()
        processes: list[subprocess.Popen[bytes]] = []
        try:
            ports = [free_port(), free_port()]
            apis = []
            for k, port in enumerate(ports):
                command = [*DRIVER, "serve", "--port", str(port), "--no-worker"]
                processes.append(_start(command, env, logs / f"api{k}.log"))
                apis.append(f"http://127.0.0.1:{port}")
            workers = {}
            for k in range(2):
                command = [*DRIVER, "worker", "--heartbeat", "0.5", "--stale-after", "4", "--reap-every", "1"]
                worker = _start(command, env, logs / f"worker{k}.log")
                processes.append(worker)
                workers[worker.pid] = worker
            for k, base in enumerate(apis):
                wait_healthy(processes[k], base, logs / f"api{k}.log", START_DEADLINE_S)
            login = httpx.post(f"{apis[0]}/api/auth/login", json={"username": "admin", "password": PASSWORD})
            assert login.status_code == 200, login.text
            headers = {"Authorization": f"Bearer {login.json()['access_token']}"}
            yield Topology(apis, workers, database_url, env, logs, headers)
        finally:
            for process in processes:
                stop(process)


def _wait_job(topology: Topology, job_id: int, api: int = 0) -> dict[str, Any]:
    deadline = time.monotonic() + JOB_DEADLINE_S
    while (job := topology.call(api, "GET", f"/jobs/{job_id}").json())["status"] in ("queued", "running"):
        assert time.monotonic() < deadline, f"job {job_id} did not end: {job}\n{topology.log_tail()}"
        time.sleep(0.5)
    return dict(job)


@pytest.fixture(scope="module")
def site(topology: Topology, tiny_site_dir: Path) -> int:
    """The tiny site imported through both APIs (drive imports run on the workers) with a first map."""
    site_id = int(topology.call(0, "POST", "/sites", json={"name": "tiny"}).json()["id"])
    survey = (tiny_site_dir / "survey.dxf").read_bytes()
    uploaded = topology.call(1, "POST", f"/sites/{site_id}/survey", files={"file": ("survey.dxf", survey)})
    assert uploaded.status_code == 201, uploaded.text
    jobs = []
    for k, folder in enumerate(drive_folders(tiny_site_dir, "map")):
        answer = topology.call(
            k % 2,
            "POST",
            f"/sites/{site_id}/drives/zip",
            files={"file": (f"{folder.name}.zip", zip_folder(folder))},
        )
        assert answer.status_code in (200, 201, 202), answer.text
        jobs.append(answer.json()["id"])
    for job_id in jobs:
        assert _wait_job(topology, job_id)["status"] == "succeeded", topology.log_tail()
    build = topology.call(1, "POST", f"/sites/{site_id}/maps", json={"preset": "fast"}).json()
    job = _wait_job(topology, build["id"])
    assert job["status"] == "succeeded", f"{job}\n{topology.log_tail()}"
    return site_id


class Watcher(threading.Thread):
    """A ``/api/live`` WebSocket client on one API process, keeping every position message."""

    def __init__(self, url: str, token: str) -> None:
        super().__init__(daemon=True)
        self.url = url
        self.token = token
        self.positions: list[dict[str, Any]] = []
        self.ready = threading.Event()
        self.done = threading.Event()

    def run(self) -> None:
        headers = {"Authorization": f"Bearer {self.token}"}
        with connect(self.url, open_timeout=30, additional_headers=headers) as socket:
            assert json.loads(socket.recv(30))["type"] == "snapshot"
            self.ready.set()
            while not self.done.is_set():
                try:
                    message = json.loads(socket.recv(0.5))
                except TimeoutError:
                    continue
                if message["type"] == "position":
                    self.positions.append(message)


class TestScaleOut:
    def test_frames_through_both_apis_are_localised_once_in_order_and_reach_every_watcher(
        self, topology: Topology, site: int, tiny_site_dir: Path
    ) -> None:
        token = topology.headers["Authorization"].removeprefix("Bearer ")
        watchers = [Watcher(base.replace("http", "ws") + "/api/live", token) for base in topology.apis]
        for watcher in watchers:
            watcher.start()
            assert watcher.ready.wait(30), "a watcher got no snapshot"
        loc = sorted(p for p in (tiny_site_dir / "drives").iterdir() if p.name.startswith("loc"))
        frames = recorded_frames(loc[0], FRAMES_PER_VEHICLE)
        vehicles = []
        for name in ("lhd-1", "lhd-2"):
            created = topology.call(0, "POST", "/vehicles", json={"name": name, "site_id": site}).json()
            vehicles.append((int(created["id"]), str(created["token"])))
        answers: dict[int, list[dict[str, Any]]] = {v: [] for v, _ in vehicles}
        failures: list[BaseException] = []

        def stream(index: int, vehicle_id: int, vehicle_token: str) -> None:
            try:
                for k, frame in enumerate(
                    frames
                ):  # frame k goes to API (k + index) % 2: both APIs alternately
                    answer = httpx.post(
                        f"{topology.apis[(k + index) % 2]}/api/vehicles/{vehicle_id}/frames",
                        params={"t": frame.t},
                        content=frame.data,
                        headers={"Authorization": f"Bearer {vehicle_token}", "Content-Type": "image/png"},
                        timeout=120.0,
                    )
                    assert answer.status_code == 200, answer.text
                    answers[vehicle_id].append(answer.json())
            except BaseException as exc:
                failures.append(exc)

        threads = [threading.Thread(target=stream, args=(i, v, t)) for i, (v, t) in enumerate(vehicles)]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        assert not failures, f"{failures}\n{topology.log_tail()}"

        sent_t = [f.t for f in frames]
        for vehicle_id, _token in vehicles:
            assert [a["status"] for a in answers[vehicle_id]] == ["processed"] * len(frames)
            rows = topology.call(0, "GET", f"/vehicles/{vehicle_id}/positions").json()
            assert sorted(r["t"] for r in rows) == sent_t, "every frame stored once"
            by_seq = sorted(rows, key=lambda r: r["seq"])
            assert [r["t"] for r in by_seq] == sent_t, "stored in the order of t"
            state = topology.call(1, "GET", f"/vehicles/{vehicle_id}/live-state").json()
            assert (state["processed"], state["skipped"], state["out_of_order"]) == (len(frames), 0, 0)
            latest = [topology.call(a, "GET", f"/vehicles/{vehicle_id}/frames/latest") for a in (0, 1)]
            assert all(r.status_code == 200 and r.content == frames[-1].data for r in latest)

        deadline = time.monotonic() + 30
        expected = {v: sent_t for v, _ in vehicles}
        while time.monotonic() < deadline:
            heard = [_heard(w.positions) for w in watchers]
            if all(h == expected for h in heard):
                break
            time.sleep(0.2)
        for watcher in watchers:
            watcher.done.set()
        assert [_heard(w.positions) for w in watchers] == [expected, expected], "each watcher, every frame"

    def test_a_worker_killed_in_the_middle_of_a_map_build_leaves_the_other_to_finish_it(
        self, topology: Topology, site: int
    ) -> None:
        # a full build: one that reused the first build's odometry could end before it is caught running
        build = topology.call(0, "POST", f"/sites/{site}/maps", json={"preset": "fast", "full": True}).json()
        deadline = time.monotonic() + JOB_DEADLINE_S
        while True:  # the build is running and has made progress: kill the worker that runs it
            assert time.monotonic() < deadline, topology.log_tail()
            ((status, worker_id, progress),) = topology.rows(
                f"SELECT status, worker_id, progress FROM jobs WHERE id = {build['id']}"
            )
            assert status in ("queued", "running"), f"the build ended before it was caught running: {status}"
            if status == "running" and progress >= 0.1:
                break
            time.sleep(0.05)
        victim = int(str(worker_id).split(":")[1])
        os.kill(victim, signal.SIGKILL)
        topology.workers.pop(victim).wait()

        job = _wait_job(topology, build["id"], api=1)
        assert job["status"] == "succeeded", f"{job}\n{topology.log_tail()}"
        ((attempts, worker_id),) = topology.rows(
            f"SELECT attempts, worker_id FROM jobs WHERE id = {build['id']}"
        )
        assert attempts == 2 and int(str(worker_id).split(":")[1]) in topology.workers, (
            "re-run by the survivor"
        )
        versions = topology.rows(f"SELECT version FROM map_versions WHERE site_id = {site} ORDER BY version")
        assert versions == [(1,), (2,)], "exactly one new map version"
        duplicates = topology.rows(
            "SELECT map_version_id, frame_id, count(*) FROM map_poses GROUP BY 1, 2 HAVING count(*) > 1"
        )
        assert duplicates == [], "no pose stored twice"
        for table in (
            "map_poses",
            "map_nodes",
            "map_node_frames",
            "map_loop_closures",
            "map_grounding_residuals",
        ):
            counts = topology.rows(
                f"SELECT v.version, count(t.*) FROM map_versions v LEFT JOIN {table} t ON t.map_version_id = v.id"
                f" WHERE v.site_id = {site} GROUP BY v.version ORDER BY v.version"
            )
            assert counts[0][1] == counts[1][1] > 0 or table == "map_loop_closures", f"{table}: {counts}"
            assert counts[0][1] == counts[1][1], f"{table}: the rebuilt version has the first one's rows"


def _heard(positions: list[dict[str, Any]]) -> dict[int, list[float]]:
    """The ``t`` of every position a watcher got, by vehicle, in arrival order."""
    out: dict[int, list[float]] = {}
    for message in positions:
        out.setdefault(int(message["vehicle_id"]), []).append(float(message["t"]))
    return out
