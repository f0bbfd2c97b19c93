"""Counters of the live path in this process, for ``GET /metrics`` (:mod:`driftmap.api.metrics`).

Process-wide: every live frame this process answers is counted once, by its status, and every localised
frame's localiser time is observed. Several API processes each expose their own (Prometheus sums them).
"""

from __future__ import annotations

from prometheus_client import CollectorRegistry, Counter, Histogram

__all__ = ["LIVE_REGISTRY", "count_frame"]

LIVE_REGISTRY = CollectorRegistry(auto_describe=True)

FRAMES = Counter(
    "driftmap_live_frames",
    "Live frames answered by this process, by status (processed, skipped, out_of_order).",
    ["status"],
    registry=LIVE_REGISTRY,
)
LOCALISE_SECONDS = Histogram(
    "driftmap_localise_seconds",
    "Localiser time of one processed live frame (decode, odometry, HMM, track), seconds.",
    buckets=(0.005, 0.01, 0.015, 0.02, 0.03, 0.05, 0.1, 0.2, 0.5, 1.0),
    registry=LIVE_REGISTRY,
)


def count_frame(status: str, localise_ms: float | None) -> None:
    """Count one answered frame; ``localise_ms`` is the localiser's time when it was processed."""
    FRAMES.labels(status=status).inc()
    if status == "processed" and localise_ms is not None:
        LOCALISE_SECONDS.observe(localise_ms / 1000.0)
