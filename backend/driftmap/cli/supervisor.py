"""The job worker beside ``driftmap serve``: started with the server, restarted when it dies, stopped with it.

:class:`WorkerSupervisor` runs ``driftmap worker --parent <server pid>`` as a child process and watches it
from a thread. A worker that exits while the server runs (killed, crashed, out of memory) is started again
after :attr:`SupervisorTimings.restart_delay_s`, doubling up to :attr:`SupervisorTimings.restart_delay_max_s`
while it keeps dying within :attr:`SupervisorTimings.stable_after_s` of its start; its running jobs are put
back on the queue by the reaper of the new worker (their heartbeat stops). The other direction:
``--parent`` makes the worker stop itself (SIGTERM, which re-queues its jobs) when the server process is
gone, even after a SIGKILL that leaves no chance to clean up.
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SupervisorTimings:
    """How the supervisor watches and restarts its worker."""

    poll_s: float = 0.5
    """How often the worker's process is checked, seconds."""
    restart_delay_s: float = 1.0
    """Wait before the first restart of a dead worker, seconds."""
    restart_delay_max_s: float = 30.0
    """Longest wait between restarts of a worker that keeps dying, seconds."""
    stable_after_s: float = 30.0
    """A worker that ran this long resets the restart delay, seconds."""
    stop_timeout_s: float = 20.0
    """How long a stopping worker may take to re-queue its jobs before it is killed, seconds."""


class WorkerSupervisor:
    """Starts, restarts and stops the ``driftmap worker`` process of ``driftmap serve``."""

    def __init__(self, timings: SupervisorTimings | None = None) -> None:
        self.timings = timings or SupervisorTimings()
        self.process: subprocess.Popen[bytes] | None = None
        self.restarts = 0
        self._stopping = threading.Event()
        self._lock = threading.Lock()
        self._thread = threading.Thread(target=self._watch, name="driftmap-worker-supervisor", daemon=True)

    def start(self) -> None:
        """Start the worker and the thread that restarts it."""
        self._spawn()
        self._thread.start()

    def _spawn(self) -> None:
        command = [sys.executable, "-m", "driftmap", "worker", "--parent", str(os.getpid())]
        with self._lock:
            if self._stopping.is_set():
                return
            self.process = subprocess.Popen(command, env=dict(os.environ))
        log.info("driftmap: worker process %d started", self.process.pid)

    def _watch(self) -> None:
        delay = self.timings.restart_delay_s
        started = time.monotonic()
        while not self._stopping.wait(self.timings.poll_s):
            process = self.process
            if process is None or process.poll() is None:
                continue
            ran_s = time.monotonic() - started
            delay = self.timings.restart_delay_s if ran_s >= self.timings.stable_after_s else delay
            log.error(
                "driftmap: worker process %d exited with %s after %.0f s; restarting it in %g s",
                process.pid,
                process.returncode,
                ran_s,
                delay,
            )
            if self._stopping.wait(delay):
                return
            delay = min(2 * delay, self.timings.restart_delay_max_s)
            started = time.monotonic()
            self.restarts += 1
            self._spawn()

    def stop(self) -> None:
        """Stop restarting; SIGTERM the worker (it re-queues its running jobs), kill it if it does not stop."""
        with self._lock:
            self._stopping.set()
        if self._thread.is_alive():
            self._thread.join()
        process = self.process
        if process is None:
            return
        if process.poll() is None:
            process.send_signal(signal.SIGTERM)
            try:
                process.wait(self.timings.stop_timeout_s)
            except subprocess.TimeoutExpired:
                process.kill()
                process.wait()
        log.info("driftmap: worker process %d stopped", process.pid)
