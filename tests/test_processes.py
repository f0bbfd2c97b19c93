"""Worker processes end with the process that started them, even when it is SIGKILLed: a map build's odometry
processes (``map build --workers N``) and, through the same :func:`driftmap.processes.end_with_parent`, the
localiser's worker processes of ``driftmap serve`` and the simulator's render processes."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

from tests.processes import alive, wait_until

EXIT_DEADLINE_S = 10.0  # a worker ends within this of its parent's death, seconds (it checks every 1 s)

# The parent stands in for the build: it starts the pool as a build does, prints its worker's pid, then waits to
# be SIGKILLed; the worker does nothing meanwhile but wait on its call queue.
MAP_BUILD_POOL = """
import multiprocessing, os, time
from concurrent.futures import ProcessPoolExecutor
from driftmap.services.map_drives import single_threaded_worker

if __name__ == "__main__":
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(1, mp_context=context, initializer=single_threaded_worker) as pool:
        print(pool.submit(os.getpid).result(), flush=True)
        time.sleep(120)
"""


def _kill_parent_then_wait_for_its_worker(script: str) -> None:
    """Run ``script`` as the parent, SIGKILL it once it printed its worker's pid and the worker ran past its
    first check; fail unless the worker is gone within ``EXIT_DEADLINE_S``."""
    parent = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        assert parent.stdout is not None
        worker = int(parent.stdout.readline())
        time.sleep(1.5)  # past its first check
        assert alive(worker), "the worker must run while its parent does"
        parent.send_signal(signal.SIGKILL)
        parent.wait(timeout=10)
        wait_until(lambda: not alive(worker), "end of the worker after its parent's", EXIT_DEADLINE_S)
    finally:
        parent.kill()


def test_a_map_builds_odometry_process_ends_with_the_build() -> None:
    _kill_parent_then_wait_for_its_worker(MAP_BUILD_POOL)


def test_a_process_that_watches_ends_with_its_parent() -> None:
    watcher = "from driftmap.processes import end_with_parent; import os, time; end_with_parent(0.05); print(os.getpid(), flush=True); time.sleep(120)"
    _kill_parent_then_wait_for_its_worker(
        f"import subprocess, sys, time; child = subprocess.Popen([sys.executable, '-c', {watcher!r}]); time.sleep(120)"
    )
