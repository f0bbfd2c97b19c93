"""The ``workers`` table: one row per running job worker process, refreshed while it runs.

``/api/health`` reads it to tell whether any worker is alive; a worker deletes its row when it stops, and
rows of killed workers are removed once long stale.
"""

from __future__ import annotations

from datetime import datetime

from sqlalchemy import String
from sqlalchemy.orm import Mapped, mapped_column

from driftmap.store.models import Base, UtcDateTime, utc_now


class WorkerProcess(Base):
    """A job worker process: ``id`` is its ``host:pid:`` prefix (that of its jobs' ``worker_id``)."""

    __tablename__ = "workers"

    id: Mapped[str] = mapped_column(String(200), primary_key=True)
    started_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now)
    seen_at: Mapped[datetime] = mapped_column(UtcDateTime(), default=utc_now, index=True)
    """Last time the worker said it was alive (every reaper round)."""
