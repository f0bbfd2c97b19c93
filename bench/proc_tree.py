"""A process and its descendants, read from Linux's ``/proc``: resident memory, CPU time and roles.

The benchmarks that run ``driftmap serve`` as a child use it to account for the server's whole tree (API
processes, localiser processes, the supervised job worker) without a dependency.
"""

from __future__ import annotations

import os
from collections import defaultdict
from pathlib import Path

TICKS_PER_S = os.sysconf("SC_CLK_TCK")


def _stat_fields(pid: int) -> list[str] | None:
    """Fields of ``/proc/<pid>/stat`` after the command name (field 3 on), or None if the process is gone."""
    try:
        text = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return text[text.rindex(")") + 2 :].split()


def descendants(root: int) -> list[int]:
    """``root`` and every live process under it."""
    kids: dict[int, list[int]] = defaultdict(list)
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit() and (fields := _stat_fields(int(entry.name))) is not None:
            kids[int(fields[1])].append(int(entry.name))
    out, todo = [], [root]
    while todo:
        pid = todo.pop()
        out.append(pid)
        todo.extend(kids.get(pid, []))
    return out


def rss_mb(pid: int) -> float:
    """Resident memory of ``pid``, MB (0 if it is gone)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return 0.0


def cpu_s(pid: int) -> float:
    """User + system CPU seconds ``pid`` has used so far (0 if it is gone)."""
    fields = _stat_fields(pid)
    return (int(fields[11]) + int(fields[12])) / TICKS_PER_S if fields else 0.0


def role(pid: int, root: int) -> str:
    """What a process of a ``driftmap serve`` tree rooted at ``root`` is: server, job worker or localiser."""
    if pid == root:
        return "server"
    try:
        text = Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
    except OSError:
        return "gone"
    if " worker" in text:
        return "job worker"
    if " serve" in text:
        return "server"
    return "localiser processes"


def tree_rss_mb(root: int) -> dict[str, float]:
    """Resident memory of ``root``'s tree, MB, summed per :func:`role`."""
    out: dict[str, float] = defaultdict(float)
    for pid in descendants(root):
        out[role(pid, root)] += rss_mb(pid)
    return dict(out)


def tree_cpu_s(root: int) -> float:
    """CPU seconds used so far by the live processes of ``root``'s tree."""
    return sum(cpu_s(pid) for pid in descendants(root))
