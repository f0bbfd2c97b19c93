"""``driftmap worker``: run background jobs (map builds, imports, localisation, simulation)."""

from __future__ import annotations

import os
import signal
import threading
import time
from typing import Annotated

import typer

from driftmap.config import get_settings
from driftmap.jobs.metrics import serve_metrics
from driftmap.jobs.worker import WorkerTimings, run_worker


def worker(
    workers: Annotated[int, typer.Option("--workers", "-w", min=1, help="Jobs run at once (threads).")] = 1,
    heartbeat: Annotated[
        float, typer.Option(help="Seconds between heartbeats of a running job.", min=0.1)
    ] = WorkerTimings.heartbeat_s,
    stale_after: Annotated[
        float, typer.Option(help="Re-queue a running job with no heartbeat for this many seconds.", min=0.5)
    ] = WorkerTimings.stale_after_s,
    reap_every: Annotated[
        float, typer.Option(help="Seconds between two looks for stale jobs.", min=0.1)
    ] = WorkerTimings.reap_every_s,
    parent: Annotated[
        int | None,
        typer.Option(help="Stop (as on SIGTERM) when process PARENT is gone; driftmap serve passes its pid."),
    ] = None,
    metrics_port: Annotated[
        int | None,
        typer.Option(
            min=1, max=65535, help="Serve this worker's Prometheus metrics on http://0.0.0.0:PORT/metrics."
        ),
    ] = None,
) -> None:
    """Run a job worker until interrupted (Ctrl-C lets running jobs finish; SIGTERM re-queues them)."""
    if stale_after <= 2 * heartbeat:
        raise typer.BadParameter("must exceed two heartbeats", param_hint="--stale-after")
    if metrics_port is not None:
        try:
            serve_metrics(metrics_port)
        except OSError as exc:
            raise typer.BadParameter(
                f"cannot serve on port {metrics_port}: {exc.strerror}", param_hint="--metrics-port"
            ) from None
    if parent is not None:
        threading.Thread(
            target=_stop_with_parent, args=(parent,), name="driftmap-parent", daemon=True
        ).start()
    run_worker(
        get_settings(),
        workers=workers,
        timings=WorkerTimings(heartbeat_s=heartbeat, stale_after_s=stale_after, reap_every_s=reap_every),
    )


def _stop_with_parent(parent_pid: int, poll_s: float = 0.5) -> None:
    """SIGTERM this process once ``parent_pid`` is no longer its parent (it died, even by SIGKILL)."""
    while os.getppid() == parent_pid:
        time.sleep(poll_s)
    os.kill(os.getpid(), signal.SIGTERM)
