"""Worker processes that end with the process that started them.

A pool worker (``ProcessPoolExecutor``, ``multiprocessing.Pool``) waits on its call queue forever: when its
parent is killed (SIGTERM, SIGKILL, a closed terminal), nothing tells it, and it goes on holding memory, the
database and the files it had open. :func:`end_with_parent`, called in a pool's initializer, watches for the
parent's death from a daemon thread and ends the worker then.
"""

from __future__ import annotations

import os
import threading
import time

__all__ = ["end_with_parent", "exit_with_parent"]

PARENT_POLL_S = 1.0
"""How often a worker checks that its parent runs, seconds."""


def end_with_parent(poll_s: float = PARENT_POLL_S) -> None:
    """End this process within ``poll_s`` seconds of its parent's death; returns at once (a daemon thread
    watches)."""
    threading.Thread(
        target=exit_with_parent, args=(os.getppid(), poll_s), name="exit-with-parent", daemon=True
    ).start()


def exit_with_parent(parent_pid: int, poll_s: float = PARENT_POLL_S) -> None:
    """Block while process ``parent_pid`` is this process's parent, then end this process at once
    (``os._exit(0)``: the parent that would collect a result is gone)."""
    while os.getppid() == parent_pid:
        time.sleep(poll_s)
    os._exit(0)
