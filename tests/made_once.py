"""Read-only test inputs made once per ``make test`` run, shared by the suite's worker processes.

``make test`` runs the suite on several processes (pytest-xdist); a simulated site takes tens of seconds to
make, and every process would make its own. :func:`made_once` makes it in the run's common temporary folder
under a file lock, so the first process makes it and the others wait for it and read it. Without xdist it
is the plain session temporary folder.
"""

from __future__ import annotations

import fcntl
import os
import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

_DONE = ".complete"


def made_once(factory: pytest.TempPathFactory, name: str, make: Callable[[Path], object]) -> Path:
    """The folder ``name``/site, made by ``make(folder)`` once for all worker processes of the run.

    Args:
        factory: the session's temporary path factory.
        name: a folder name unique to this input.
        make: writes the input into the (not yet existing) folder it is given.

    Returns:
        The folder (read-only for tests).
    """
    if os.environ.get("PYTEST_XDIST_WORKER") is None:
        out = factory.mktemp(name) / "site"
        make(out)
        return out
    root = factory.getbasetemp().parent / name  # the run's folder, shared by its workers
    root.mkdir(exist_ok=True)
    with (root / ".lock").open("w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes
        if not (root / _DONE).exists():
            shutil.rmtree(root / "site", ignore_errors=True)  # a worker that failed half-way
            make(root / "site")
            (root / _DONE).touch()
    return root / "site"
