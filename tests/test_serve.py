"""``driftmap serve`` as a real process: uvicorn on a free port and a worker process beside it."""

from __future__ import annotations

import asyncio
import json
import re
import signal
import struct
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
import websockets

from driftmap.config import Settings
from driftmap.services import users as user_service
from driftmap.store.storage import Storage
from tests.api.access_helpers import built_tiny_data, copy_data, localisation_drive, recorded_frames
from tests.processes import alive, driftmap_env, start_server

pytestmark = pytest.mark.slow  # real server and worker processes

START_DEADLINE_S = 90.0
STOP_DEADLINE_S = 60.0


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
        assert httpx.get(f"{base}/api/health").json()["status"] == "ok"
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
            url = base.replace("http", "ws") + f"/api/live?token={token}"
            async with websockets.connect(url) as ws:
                message: dict = json.loads(await asyncio.wait_for(ws.recv(), 30.0))  # type: ignore[type-arg]
                return message

        assert asyncio.run(snapshot())["type"] == "snapshot"

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
                live_url = f"{ws_base}/api/live?token={login.json()['access_token']}"
                async with websockets.connect(live_url) as live, httpx.AsyncClient(base_url=base) as client:
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
