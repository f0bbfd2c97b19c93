"""Prometheus metrics of a worker process, served on its own port (``driftmap worker --metrics-port``).

The API's ``GET /metrics`` counts jobs by status from the database (every process sees the same rows); what only
the worker knows is how long each job ran and how it ended, observed here for every job this process ran, and
when the process started (a restart shows as a jump). Whether any worker is alive is the API's to say
(``GET /api/health``, from the workers' heartbeats); the port answering only says this process runs.
"""

from __future__ import annotations

import time

from prometheus_client import CollectorRegistry, Gauge, Histogram, start_http_server

__all__ = ["WORKER_REGISTRY", "observe_job", "serve_metrics"]

WORKER_REGISTRY = CollectorRegistry(auto_describe=True)

JOB_SECONDS = Histogram(
    "driftmap_job_seconds",
    "Run time of a job in this worker process, seconds, by kind and outcome (succeeded, failed, cancelled, "
    "retried, lost).",
    ["kind", "outcome"],
    buckets=(0.1, 0.5, 1, 5, 15, 60, 180, 600, 1800, 3600),
    registry=WORKER_REGISTRY,
)
STARTED = Gauge(
    "driftmap_worker_started_seconds",
    "When this worker process started, seconds since the epoch.",
    registry=WORKER_REGISTRY,
)


def observe_job(kind: str, outcome: str, seconds: float) -> None:
    """Record one job run by this process: its ``kind``, how it ended and its run time in seconds."""
    JOB_SECONDS.labels(kind=kind, outcome=outcome).observe(max(seconds, 0.0))


def serve_metrics(port: int, host: str = "0.0.0.0") -> None:
    """Serve this process's metrics at ``http://HOST:PORT/metrics`` from a background thread."""
    STARTED.set(time.time())
    start_http_server(port, addr=host, registry=WORKER_REGISTRY)
