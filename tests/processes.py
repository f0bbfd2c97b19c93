"""Helpers for tests that run real processes: free loopback ports, liveness, a server's health wait, stopping."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import httpx


def driftmap_env(data_dir: Path, database_url: str | None = None, **settings: str) -> dict[str, str]:
    """The environment of a ``driftmap`` subprocess: this one without its ``DRIFTMAP_*`` settings, then
    ``DRIFTMAP_DATA_DIR``, the run's database (``database_url``, else this process's
    ``DRIFTMAP_DATABASE_URL`` on a PostgreSQL run) and ``settings`` as ``DRIFTMAP_<NAME>`` variables."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("DRIFTMAP_")}
    env["DRIFTMAP_DATA_DIR"] = str(data_dir)
    url = database_url or os.environ.get("DRIFTMAP_DATABASE_URL")
    if url:
        env["DRIFTMAP_DATABASE_URL"] = url
    env.update({f"DRIFTMAP_{name.upper()}": value for name, value in settings.items()})
    return env


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port: int = sock.getsockname()[1]
        return port


def alive(pid: int) -> bool:
    """Whether process ``pid`` runs; a zombie (exited, not yet reaped) counts as stopped."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    try:
        return "\nState:\tZ" not in Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:  # reaped in between
        return False


def wait_until(condition: Callable[[], bool], what: str, deadline_s: float) -> None:
    """Poll ``condition`` until it holds; fail naming ``what`` at the deadline."""
    deadline = time.monotonic() + deadline_s
    while not condition():
        assert time.monotonic() < deadline, f"no {what} within {deadline_s} s"
        time.sleep(0.2)


def wait_healthy(process: subprocess.Popen[bytes], base: str, log: Path, deadline_s: float) -> None:
    """Wait until the server at ``base`` answers ``/api/health``; fail with its log if it exits or times out."""
    deadline = time.monotonic() + deadline_s
    while True:
        assert process.poll() is None, log.read_text()
        try:
            if httpx.get(f"{base}/api/health", timeout=2.0).status_code == 200:
                return
        except httpx.TransportError:
            pass
        assert time.monotonic() < deadline, f"no health answer within {deadline_s} s:\n{log.read_text()}"
        time.sleep(0.2)


def start_server(
    env: dict[str, str], log: Path, *extra: str, deadline_s: float = 120.0
) -> tuple[subprocess.Popen[bytes], str]:
    """Start ``driftmap serve`` on a free port with ``extra`` arguments, output to ``log``; wait for its health
    answer. Returns the process and its base URL; a server that does not come up is stopped before failing."""
    port = free_port()
    with log.open("wb") as sink:
        process = subprocess.Popen(
            [sys.executable, "-m", "driftmap", "serve", "--port", str(port), *extra],
            env=env,
            stdout=sink,
            stderr=sink,
        )
    base = f"http://127.0.0.1:{port}"
    try:
        wait_healthy(process, base, log, deadline_s)
    except BaseException:
        stop(process)
        raise
    return process, base


def stop(process: subprocess.Popen[bytes], timeout_s: float = 30.0) -> None:
    """SIGTERM, then SIGKILL when it has not ended within ``timeout_s``."""
    process.terminate()
    try:
        process.wait(timeout_s)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
