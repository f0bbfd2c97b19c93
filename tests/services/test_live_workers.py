"""Localiser worker processes do not outlive the server process that started them."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie (exited, not reaped yet by init) counts as gone.
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().split(") ", 1)[1][0] != "Z"
    except FileNotFoundError:  # reaped in between
        return False


def test_a_worker_exits_when_its_parent_is_killed() -> None:
    child = (
        "from driftmap.services.live_workers import _exit_with_parent; print('ready', flush=True); "
        "_exit_with_parent($$, poll_s=0.05)"
    )
    # The parent stands in for the server: it starts the worker, prints its pid, then is SIGKILLed.
    parent = subprocess.Popen(
        ["bash", "-c", f'{sys.executable} -c "{child}" & echo $!; sleep 60'],
        stdout=subprocess.PIPE,
        text=True,
    )
    assert parent.stdout is not None
    worker = int(parent.stdout.readline())
    assert parent.stdout.readline().strip() == "ready"
    time.sleep(0.5)  # ten polls
    assert _alive(worker), "the worker must run while its parent does"
    parent.send_signal(signal.SIGKILL)
    parent.wait(timeout=10)
    deadline = time.monotonic() + 10
    while _alive(worker) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not _alive(worker)
