"""A private ``redis-server`` for tests: a free loopback port, no persistence, stopped afterwards.

A test module wraps :func:`running_redis` in its own ``redis_url`` fixture; the test is skipped when
redis-server is not installed (``make test`` installs it).
"""

from __future__ import annotations

import shutil
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import redis

from tests.processes import free_port, stop

START_DEADLINE_S = 30.0


@contextmanager
def running_redis(directory: Path) -> Iterator[str]:
    """Start redis-server in ``directory``; yields its URL (database 0) and stops it on exit."""
    binary = shutil.which("redis-server")
    if binary is None:
        pytest.skip("redis-server is not installed")
    port = free_port()
    dies_with_us = ["setpriv", "--pdeathsig=TERM"] if shutil.which("setpriv") else []  # even when killed
    server = subprocess.Popen(
        [
            *dies_with_us,
            binary,
            "--port",
            str(port),
            "--bind",
            "127.0.0.1",
            "--save",
            "",
            "--appendonly",
            "no",
        ],
        cwd=directory,
        stdout=subprocess.DEVNULL,
    )
    url = f"redis://127.0.0.1:{port}/0"
    try:
        client = redis.Redis.from_url(url)
        deadline = time.monotonic() + START_DEADLINE_S
        while True:
            try:
                client.ping()
                break
            except redis.ConnectionError:
                assert server.poll() is None, "redis-server exited at start"
                assert time.monotonic() < deadline, "redis-server did not start"
                time.sleep(0.1)
        client.close()
        yield url
    finally:
        stop(server)
