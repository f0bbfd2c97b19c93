"""The ``jobs`` table: one row per background job, the single source of truth on its state.

The huey queue only carries job ids; a worker reads the row, marks it running, reports progress and a
heartbeat on it in short transactions, and writes its final status and result. Timestamps are UTC.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any

from sqlalchemy import JSON, Float, ForeignKey, Index, Integer, String, Text, text
from sqlalchemy.orm import Mapped, mapped_column

from driftmap.store.models import Base, UtcDateTime, utc_now

JOB_STATUSES = ("queued", "running", "succeeded", "failed", "cancelled")
"""Every value of :attr:`Job.status`; the last three are final."""

ACTIVE_SITE_BUILD = text("kind = 'map.build' AND parent_id IS NULL AND status IN ('queued', 'running')")
"""The rows the index ``uq_jobs_site_id_active_build`` covers: a site's map build that has not ended."""


class Job(Base):
    """A background job (``map.build``, ``drive.localise``, ``drive.import``, ``site.simulate``).

    A subtask of another job (``map.drive``: one drive's odometry of a ``map.build``) names it in ``parent_id``;
    any worker may run it, and it is deleted with its parent.

    ``progress`` runs from 0 to 1 within the named ``stage``; ``attempts`` counts how many times a worker
    started it; ``heartbeat_at`` is refreshed by the running worker so that a stale one can be re-queued.
    A cancel request on a running job sets ``cancel_requested_at``; the worker stops at its next progress
    report. A site has at most one ``map.build`` that is queued or running (a partial unique index).
    """

    __tablename__ = "jobs"
    __table_args__ = (
        # one unfinished map build per site, even when two requests race past the service's check
        Index(
            "uq_jobs_site_id_active_build",
            "site_id",
            unique=True,
            sqlite_where=ACTIVE_SITE_BUILD,
            postgresql_where=ACTIVE_SITE_BUILD,
        ),
    )

    id: Mapped[int] = mapped_column(primary_key=True)
    kind: Mapped[str] = mapped_column(String(50), index=True)
    site_id: Mapped[int | None] = mapped_column(
        ForeignKey("sites.id", ondelete="CASCADE"), index=True, nullable=True
    )
    args: Mapped[dict[str, Any]] = mapped_column(JSON)
    status: Mapped[str] = mapped_column(String(20), index=True, default="queued")
    progress: Mapped[float] = mapped_column(Float, default=0.0)
    stage: Mapped[str] = mapped_column(String(200), default="")
    error: Mapped[str | None] = mapped_column(Text, nullable=True)
    result: Mapped[dict[str, Any] | None] = mapped_column(JSON, nullable=True)
    attempts: Mapped[int] = mapped_column(Integer, default=0)
    created_by: Mapped[str] = mapped_column(String(200), default="")
    created_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)
    started_at: Mapped[datetime | None] = mapped_column(UtcDateTime(), nullable=True)
    finished_at: Mapped[datetime | None] = mapped_column(UtcDateTime(), nullable=True)
    heartbeat_at: Mapped[datetime | None] = mapped_column(UtcDateTime(), nullable=True)
    cancel_requested_at: Mapped[datetime | None] = mapped_column(UtcDateTime(), nullable=True)
    worker_id: Mapped[str | None] = mapped_column(String(200), nullable=True)
    parent_id: Mapped[int | None] = mapped_column(
        ForeignKey("jobs.id", ondelete="CASCADE"), index=True, nullable=True
    )
