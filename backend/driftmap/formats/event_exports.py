"""The control room's event log as a CSV file (``docs/formats.md``, Events).

One line per event: when its condition started and ended (ISO 8601, UTC, milliseconds), how long it lasted
(seconds, empty while it lasts), where the vehicle was when it started (site plane metres, empty when not
known) and who acknowledged it when.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from datetime import UTC, datetime

from driftmap.formats.tables import format_optional_float, table_text

EVENTS_HEADER: tuple[str, ...] = (
    "id", "site_id", "vehicle", "kind", "detail", "started_at", "ended_at", "duration_s", "x", "y",
    "acknowledged_by", "acknowledged_at",
)  # fmt: skip


@dataclass(frozen=True)
class EventRow:
    """One event of one vehicle; times aware UTC, ``x_m, y_m`` site plane metres (east, north)."""

    id: int
    site_id: int
    vehicle: str
    kind: str
    detail: str | None
    started_at: datetime
    ended_at: datetime | None
    x_m: float | None
    y_m: float | None
    acknowledged_by: str | None
    acknowledged_at: datetime | None


def iso_utc(moment: datetime | None) -> str:
    """``YYYY-MM-DDTHH:MM:SS.mmmZ`` of an aware time, empty for None."""
    if moment is None:
        return ""
    return moment.astimezone(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _duration(row: EventRow) -> str:
    if row.ended_at is None:
        return ""
    return f"{(row.ended_at - row.started_at).total_seconds():.3f}"


def events_text(rows: Iterable[EventRow]) -> str:
    """Events CSV text, header ``id,site_id,vehicle,kind,detail,started_at,ended_at,duration_s,x,y,...``."""
    return table_text(
        EVENTS_HEADER,
        (
            [
                str(r.id),
                str(r.site_id),
                r.vehicle,
                r.kind,
                r.detail or "",
                iso_utc(r.started_at),
                iso_utc(r.ended_at),
                _duration(r),
                format_optional_float(r.x_m, field="x"),
                format_optional_float(r.y_m, field="y"),
                r.acknowledged_by or "",
                iso_utc(r.acknowledged_at),
            ]
            for r in rows
        ),
    )
