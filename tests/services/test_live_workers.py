"""Localiser worker processes do not outlive the server process that started them."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

from tests.processes import alive


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
    assert alive(worker), "the worker must run while its parent does"
    parent.send_signal(signal.SIGKILL)
    parent.wait(timeout=10)
    deadline = time.monotonic() + 10
    while alive(worker) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not alive(worker)
