"""``driftmap serve`` as a real process: uvicorn on a free port and a worker process beside it."""

from __future__ import annotations

import asyncio
import json
import os
import re
import signal
import struct
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import httpx
import pytest
import websockets

from driftmap.config import Settings
from driftmap.services import users as user_service
from driftmap.store.storage import Storage
from tests.api.access_helpers import built_tiny_data, copy_data, localisation_drive, recorded_frames
from tests.processes import alive, driftmap_env, start_server, wait_until

pytestmark = pytest.mark.slow  # real server and worker processes

START_DEADLINE_S = 90.0
STOP_DEADLINE_S = 60.0
JOB_DEADLINE_S = 240.0


def _wait_until(condition: Callable[[], bool], what: str, deadline_s: float = START_DEADLINE_S) -> None:
    wait_until(condition, what, deadline_s)


@pytest.fixture
def env(tmp_path: Path) -> dict[str, str]:
    return driftmap_env(tmp_path / "data")


def _serve(
    env: dict[str, str], log: Path, *extra: str
) -> Iterator[tuple[subprocess.Popen[bytes], str, Path]]:
    """Start ``driftmap serve`` and wait for its health answer; the second ``next`` kills what is left."""
    process, base = start_server(env, log, *extra, deadline_s=START_DEADLINE_S)
    yield process, base, log
    if process.poll() is None:
        process.kill()
        process.wait()


@pytest.fixture
def server(env: dict[str, str], tmp_path: Path) -> Iterator[tuple[subprocess.Popen[bytes], str, Path]]:
    yield from _serve(env, tmp_path / "serve.log")


class TestServe:
    def test_health_login_live_socket_and_clean_shutdown(
        self, server: tuple[subprocess.Popen[bytes], str, Path], env: dict[str, str]
    ) -> None:
        process, base, log = server
        _wait_until(
            lambda: httpx.get(f"{base}/api/health").json()["status"] == "ok", "health ok with its worker"
        )
        assert httpx.get(f"{base}/api/health").json()["workers"] == 1
        assert httpx.get(f"{base}/docs").status_code == 200
        worker_pid = int(re.search(r"worker process (\d+) started", log.read_text()).group(1))  # type: ignore[union-attr]
        assert alive(worker_pid)

        added = subprocess.run(
            [sys.executable, "-m", "driftmap", "user", "add", "ops", "--role", "viewer", "--password-stdin"],
            input=b"long-password\n",
            env=env,
            capture_output=True,
            check=False,
        )
        assert added.returncode == 0, added.stderr.decode()
        login = httpx.post(f"{base}/api/auth/login", json={"username": "ops", "password": "long-password"})
        token = login.json()["access_token"]

        async def snapshot() -> dict:  # type: ignore[type-arg]
            url = base.replace("http", "ws") + "/api/live"
            async with websockets.connect(url) as ws:  # as a browser does: the token in the first message
                await ws.send(json.dumps({"type": "auth", "token": token}))
                message: dict = json.loads(await asyncio.wait_for(ws.recv(), 30.0))  # type: ignore[type-arg]
                return message

        assert asyncio.run(snapshot())["type"] == "snapshot"
        _assert_no_query_strings_logged(base, log)

        process.send_signal(signal.SIGTERM)
        assert process.wait(STOP_DEADLINE_S) == 0 or process.returncode == 128 + signal.SIGTERM
        deadline = time.monotonic() + STOP_DEADLINE_S
        while alive(worker_pid):
            assert time.monotonic() < deadline, "the worker process outlived the server"
            time.sleep(0.2)
        assert "worker process" in log.read_text() and "stopped" in log.read_text()


class TestLiveOnARealServer:
    def test_frames_over_http_and_websocket_reach_live_watchers(
        self,
        env: dict[str, str],
        tmp_path: Path,
        tmp_path_factory: pytest.TempPathFactory,
        tiny_site_dir: Path,
    ) -> None:
        data = copy_data(built_tiny_data(tmp_path_factory.getbasetemp(), tiny_site_dir), tmp_path / "data")
        storage = Storage.open(Settings(data_dir=data))
        with storage.db.session() as session:
            user_service.create_user(session, "boss", "long-password", "admin")
        storage.close()
        env = {**env, "DRIFTMAP_DATA_DIR": str(data)}
        frames = recorded_frames(localisation_drive(tiny_site_dir), 30)
        served = _serve(env, tmp_path / "serve.log", "--no-worker")
        _process, base, _log = next(served)
        try:
            login = httpx.post(
                f"{base}/api/auth/login", json={"username": "boss", "password": "long-password"}
            )
            admin = {"Authorization": f"Bearer {login.json()['access_token']}"}
            vehicle = httpx.post(
                f"{base}/api/vehicles", json={"name": "lhd", "site_id": 1}, headers=admin
            ).json()
            mine = {"Authorization": f"Bearer {vehicle['token']}"}
            ws_base = base.replace("http", "ws")

            async def run() -> tuple[list[dict], list[dict], list[dict]]:  # type: ignore[type-arg]
                live_url = f"{ws_base}/api/live"
                async with (
                    websockets.connect(live_url, additional_headers=admin) as live,
                    httpx.AsyncClient(base_url=base) as client,
                ):
                    assert json.loads(await live.recv())["type"] == "snapshot"
                    answers = []
                    for f in frames[:20]:
                        response = await client.post(
                            f"/api/vehicles/{vehicle['id']}/frames",
                            params={"t": f.t},
                            content=f.data,
                            headers={**mine, "Content-Type": "image/png"},
                        )
                        answers.append(response.json())
                    stream_url = f"{ws_base}/api/vehicles/{vehicle['id']}/stream"
                    async with websockets.connect(stream_url, additional_headers=mine) as stream:
                        for f in frames[20:30]:
                            await stream.send(struct.pack(">d", f.t) + f.data)
                        streamed = [
                            json.loads(await asyncio.wait_for(stream.recv(), 60.0)) for _ in range(10)
                        ]
                    processed = len(answers) + sum(a["status"] == "processed" for a in streamed)
                    updates = [
                        json.loads(await asyncio.wait_for(live.recv(), 60.0)) for _ in range(processed)
                    ]
                return answers, streamed, updates

            answers, streamed, updates = asyncio.run(run())
        finally:
            next(served, None)
        assert [a["status"] for a in answers] == ["processed"] * 20
        assert sorted(a["t"] for a in streamed) == [f.t for f in frames[20:30]]
        assert [u["seq"] for u in updates[:20]] == [a["seq"] for a in answers]
        assert [u["t"] for u in updates] == sorted(u["t"] for u in updates)


def _children(pid: int) -> list[int]:
    """Pids of the processes whose parent is ``pid`` (from /proc)."""
    found = []
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except (FileNotFoundError, ProcessLookupError, IndexError):
            continue
        if int(fields[1]) == pid:
            found.append(int(stat.parent.name))
    return found


def _worker_pids(log: Path) -> list[int]:
    return [int(pid) for pid in re.findall(r"worker process (\d+) started", log.read_text())]


def _assert_no_query_strings_logged(base: str, log: Path) -> None:
    """A token passed in URLs (HTTP and WebSocket) is refused and does not reach the server's log."""
    secret = "dmv_1_" + "S3cret" * 7  # shaped like a vehicle token
    assert httpx.get(f"{base}/api/auth/me", params={"token": secret}).status_code == 401

    async def refused() -> int | None:
        async with websockets.connect(base.replace("http", "ws") + f"/api/live?token={secret}") as ws:
            with pytest.raises(websockets.ConnectionClosed) as closed:
                await asyncio.wait_for(ws.recv(), 30.0)
            return closed.value.rcvd.code if closed.value.rcvd else None

    assert asyncio.run(refused()) == 4401
    _wait_until(
        lambda: "GET /api/auth/me HTTP" in log.read_text() and '"WebSocket /api/live"' in log.read_text(),
        "access log lines",
    )
    assert secret not in log.read_text() and "token=" not in log.read_text()


class TestSupervision:
    def test_a_killed_worker_is_restarted_and_a_job_then_finishes_once(
        self, server: tuple[subprocess.Popen[bytes], str, Path], env: dict[str, str]
    ) -> None:
        _process, base, log = server
        storage = Storage.open(Settings(data_dir=Path(env["DRIFTMAP_DATA_DIR"])))
        with storage.db.session() as session:
            user_service.create_user(session, "boss", "long-password", "admin")
        storage.close()
        _wait_until(lambda: len(_worker_pids(log)) == 1, "worker start")
        first = _worker_pids(log)[0]
        os.kill(first, signal.SIGKILL)
        _wait_until(lambda: len(_worker_pids(log)) == 2, "worker restart")
        second = _worker_pids(log)[1]
        assert second != first and alive(second) and not alive(first)
        assert f"worker process {first} exited with -9" in log.read_text()

        login = httpx.post(f"{base}/api/auth/login", json={"username": "boss", "password": "long-password"})
        admin = {"Authorization": f"Bearer {login.json()['access_token']}"}
        body = {"name": "sim", "size": "tiny", "max_frames_per_drive": 4}
        job = httpx.post(f"{base}/api/sites/simulate", json=body, headers=admin).json()

        def finished() -> bool:
            answer = httpx.get(f"{base}/api/jobs/{job['id']}", headers=admin).json()
            return answer["status"] in ("succeeded", "failed", "cancelled")

        _wait_until(finished, "finished job", JOB_DEADLINE_S)
        done = httpx.get(f"{base}/api/jobs/{job['id']}", headers=admin).json()
        assert (done["status"], done["attempts"]) == ("succeeded", 1), done
        assert done["worker_id"].split(":")[1] == str(second)
        sites = httpx.get(f"{base}/api/sites", headers=admin).json()["items"]
        assert [s["name"] for s in sites] == ["sim"]
        assert httpx.get(f"{base}/api/health").json()["workers"] >= 1

    def test_a_killed_server_leaves_no_process_behind(
        self, server: tuple[subprocess.Popen[bytes], str, Path]
    ) -> None:
        process, _base, log = server
        _wait_until(lambda: len(_worker_pids(log)) == 1, "worker start")
        children = _children(process.pid)
        assert _worker_pids(log)[0] in children
        process.send_signal(signal.SIGKILL)
        process.wait()
        _wait_until(
            lambda: not any(alive(pid) for pid in children), "end of the server's children", STOP_DEADLINE_S
        )


class TestJsonLogs:
    def test_every_line_is_json_and_requests_carry_their_id(
        self, env: dict[str, str], tmp_path: Path
    ) -> None:
        log = tmp_path / "serve.log"
        running = _serve(env | {"DRIFTMAP_LOG_FORMAT": "json"}, log)
        _process, base, _log = next(running)
        try:
            answer = httpx.get(f"{base}/api/health", headers={"X-Request-ID": "probe-42"})
            assert answer.headers["x-request-id"] == "probe-42"
            assert len(httpx.get(f"{base}/api/health").headers["x-request-id"]) == 32  # a new one

            def logged() -> list[dict]:  # type: ignore[type-arg]
                lines = [line for line in log.read_text().splitlines() if line.strip()]
                return [json.loads(line) for line in lines]  # fails on any line that is not JSON

            _wait_until(lambda: any(r.get("request_id") == "probe-42" for r in logged()), "access log line")
            access = next(r for r in logged() if r.get("request_id") == "probe-42")
            assert "GET /api/health" in access["message"] and access["level"] == "INFO"
            assert {"time", "logger"} <= set(access)
        finally:
            next(running, None)
