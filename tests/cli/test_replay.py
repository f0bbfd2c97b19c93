"""``driftmap replay`` against a real ``driftmap serve``: the frames reach the frame endpoint and are stored."""

from __future__ import annotations

import os
import re
import signal
import stat
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import httpx
import pytest
from prometheus_client.parser import text_string_to_metric_families

from tests.api.access_helpers import built_tiny_data, copy_data, localisation_drive
from tests.processes import alive, driftmap_env, free_port, start_server, stop

pytestmark = pytest.mark.slow  # a real server and replay processes

PASSWORD = "replay-admin-password"
START_DEADLINE_S = 120.0


@pytest.fixture
def env(tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path, tmp_path: Path) -> dict[str, str]:
    """A private copy of the tiny site with its map, and an admin user."""
    data = copy_data(built_tiny_data(tmp_path_factory.getbasetemp(), tiny_site_dir), tmp_path / "data")
    out = driftmap_env(data)
    added = subprocess.run(
        [sys.executable, "-m", "driftmap", "user", "add", "admin", "--role", "admin", "--password-stdin"],
        input=f"{PASSWORD}\n".encode(),
        env=out,
        capture_output=True,
        check=False,
    )
    assert added.returncode == 0, added.stderr.decode()
    return out


def _login(base: str) -> dict[str, str]:
    answer = httpx.post(f"{base}/api/auth/login", json={"username": "admin", "password": PASSWORD})
    assert answer.status_code == 200, answer.text
    return {"Authorization": f"Bearer {answer.json()['access_token']}"}


def _positions(base: str, auth: dict[str, str], name: str) -> list[dict]:  # type: ignore[type-arg]
    vehicles = httpx.get(f"{base}/api/vehicles", headers=auth).json()
    ids = [v["id"] for v in vehicles if v["name"] == name]
    if not ids:
        return []
    rows: list[dict] = httpx.get(f"{base}/api/vehicles/{ids[0]}/positions", headers=auth).json()  # type: ignore[type-arg]
    return rows


def _stored(base: str, name: str) -> bool:
    """Whether the server answers and holds a position of vehicle ``name``."""
    try:
        return bool(_positions(base, _login(base), name))
    except httpx.TransportError:
        return False


@pytest.fixture
def server(env: dict[str, str], tmp_path: Path) -> Iterator[str]:
    """``driftmap serve`` (no job worker) on a free port; yields its base URL."""
    process, base = start_server(env, tmp_path / "serve.log", "--no-worker", deadline_s=START_DEADLINE_S)
    try:
        yield base
    finally:
        stop(process)


def _assert_metrics_count_the_replay(base: str, frames: int) -> None:
    """``GET /metrics`` of the (one-process) server, parsed: the replayed frames, their localiser times and
    requests, and the replay's vehicle reporting."""
    values: dict[tuple[str, tuple[tuple[str, str], ...]], float] = {}
    for family in text_string_to_metric_families(httpx.get(f"{base}/metrics").text):
        for sample in family.samples:
            values[(sample.name, tuple(sorted(sample.labels.items())))] = sample.value
    assert values[("driftmap_live_frames_total", (("status", "processed"),))] == frames
    assert values[("driftmap_localise_seconds_count", ())] == frames
    assert 0.0 < values[("driftmap_localise_seconds_sum", ())] < 10.0 * frames
    route = (("method", "POST"), ("route", "/api/vehicles/{vehicle_id}/frames"), ("status", "200"))
    assert values[("driftmap_http_request_duration_seconds_count", route)] == frames
    assert values[("driftmap_vehicles", (("state", "reporting"),))] == 1
    assert values[("driftmap_jobs", (("status", "queued"),))] == 0


def _replay(env: dict[str, str], *args: str) -> list[str]:
    return [sys.executable, "-m", "driftmap", "replay", *args, "--password-stdin", "--status-every", "1"]


class TestReplay:
    def test_frames_are_localised_and_stored_at_the_recorded_pace(
        self, server: str, env: dict[str, str], tiny_site_dir: Path
    ) -> None:
        drive = localisation_drive(tiny_site_dir)
        started = time.monotonic()
        done = subprocess.run(
            _replay(env, "tiny", str(drive), "--url", server, "--once", "--max-frames", "6"),
            input=f"{PASSWORD}\n".encode(),
            env=env,
            capture_output=True,
            timeout=180,
            check=False,
        )
        output = done.stdout.decode() + done.stderr.decode()
        assert done.returncode == 0, output
        assert f"{drive.name} (vehicle " in output
        assert "6 sent, 6 localised" in output, output
        rows = _positions(server, _login(server), drive.name)
        assert len(rows) == 6
        times = [r["t"] for r in rows]
        assert times == sorted(times) and len(set(times)) == 6
        assert times[0] > 1.6e9  # the wall clock at sending
        # the tiny drive's frames are 0.1 s apart: six frames take at least half a second of replay
        assert times[-1] - times[0] >= 0.45
        assert time.monotonic() - started >= 0.5
        assert all(isinstance(r["x"], float) and 0.0 <= r["confidence"] <= 1.0 for r in rows)
        # the vehicle was given its drive's camera, so its frames after the first carry odometry
        vehicles = httpx.get(f"{server}/api/vehicles", headers=_login(server)).json()
        assert [v["has_camera"] for v in vehicles if v["name"] == drive.name] == [True]
        assert any(r["odometry"] for r in rows[1:])
        _assert_metrics_count_the_replay(server, frames=6)

        again = subprocess.run(  # a second run reuses the vehicle with a fresh token and its clock goes on
            _replay(env, "tiny", str(drive), "--url", server, "--once", "--max-frames", "2"),
            input=f"{PASSWORD}\n".encode(),
            env=env,
            capture_output=True,
            timeout=180,
            check=False,
        )
        assert again.returncode == 0, again.stderr.decode()
        assert len(_positions(server, _login(server), drive.name)) == 8

    def test_serve_mode_runs_the_server_and_ctrl_c_stops_everything(
        self, env: dict[str, str], tiny_site_dir: Path, tmp_path: Path
    ) -> None:
        drive = localisation_drive(tiny_site_dir)
        base = f"http://127.0.0.1:{free_port()}"
        log = tmp_path / "replay.log"
        with log.open("wb") as sink:
            process = subprocess.Popen(
                _replay(env, "tiny", str(drive), "--url", base, "--serve", "--show-login"),
                stdin=subprocess.PIPE,
                stdout=sink,
                stderr=sink,
                env=env,
            )
        assert process.stdin is not None
        process.stdin.write(f"{PASSWORD}\n".encode())
        process.stdin.close()
        try:
            deadline = time.monotonic() + START_DEADLINE_S
            while not _stored(base, drive.name):
                assert process.poll() is None, log.read_text()
                assert time.monotonic() < deadline, log.read_text()
                time.sleep(0.5)
            text = log.read_text()
            assert f"log in as 'admin' with password '{PASSWORD}'" in text
            server_pid = int(re.search(r"server process (\d+) starting", text).group(1))  # type: ignore[union-attr]
            assert alive(server_pid)
            process.send_signal(signal.SIGINT)
            assert process.wait(90) == 0, log.read_text()
        finally:
            if process.poll() is None:
                process.kill()
                process.wait()
            # a replay killed before it could stop its server (its own session) leaves it: stop it here
            started = re.search(r"server process (\d+) starting", log.read_text())
            if started and alive(int(started.group(1))):
                os.kill(int(started.group(1)), signal.SIGTERM)
        text = log.read_text()
        assert "stopping the replay" in text and f"server process {server_pid} stopped" in text
        serve_log = Path(env["DRIFTMAP_DATA_DIR"]) / "serve.log"
        assert stat.S_IMODE(serve_log.stat().st_mode) == 0o600  # only its owner reads the server's log
        assert not alive(server_pid)
        with pytest.raises(httpx.TransportError):
            httpx.get(f"{base}/api/health", timeout=2.0)
