"""Survey control tables (``docs/formats.md``): the station and enabled cells of ``groundings.csv``, a site's
control file ``drive,frame,station,x,y,enabled`` and a map version's residuals CSV.

Positions are survey-frame metres (x east, y north). Parsers raise :class:`BadInputError` naming the file,
the 1-based line (the header is line 1) and the column; floats are written with :func:`repr` so that
reading gives back the identical float.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from driftmap.errors import BadInputError
from driftmap.formats.records import STATION_MAX_CHARS, SiteGroundingRow
from driftmap.formats.tables import (
    format_float,
    format_optional_float,
    parse_float,
    parse_int,
    parse_text,
    read_table,
    table_text,
)

CONTROL_HEADER: tuple[str, ...] = ("drive", "frame", "station", "x", "y", "enabled")
RESIDUALS_HEADER: tuple[str, ...] = ("drive", "frame", "station", "x", "y", "residual_m", "enabled")
_TRUE = frozenset({"true", "1", "yes", ""})
_FALSE = frozenset({"false", "0", "no"})


def parse_enabled(text: str, *, file: str | Path, line: int, field: str = "enabled") -> bool:
    """An ``enabled`` cell: true/false, 1/0 or yes/no (any case); an empty cell is true."""
    value = text.strip().lower()
    if value in _TRUE:
        return True
    if value in _FALSE:
        return False
    raise BadInputError(
        f"'{text[:40]}' is not true or false (also 1/0, yes/no)", file=file, line=line, field=field
    )


def parse_station(text: str, *, file: str | Path, line: int, field: str = "station") -> str | None:
    """A ``station`` cell: a survey station id of at most ``STATION_MAX_CHARS`` characters; empty is None."""
    value = text.strip()
    if not value:
        return None
    if len(value) > STATION_MAX_CHARS:
        raise BadInputError(
            f"station id longer than {STATION_MAX_CHARS} characters", file=file, line=line, field=field
        )
    return value


def format_enabled(enabled: bool) -> str:
    """``true`` or ``false``."""
    return "true" if enabled else "false"


def control_text(rows: Iterable[SiteGroundingRow]) -> str:
    """A site's control file: header ``drive,frame,station,x,y,enabled``, one row per grounding."""
    return table_text(
        CONTROL_HEADER,
        (
            [
                r.drive,
                str(int(r.frame)),
                r.station or "",
                format_float(r.x_m, field="x"),
                format_float(r.y_m, field="y"),
                format_enabled(r.enabled),
            ]
            for r in rows
        ),
    )


def parse_control_rows(text: str, file: str | Path) -> list[tuple[int, SiteGroundingRow]]:
    """Parse a site's control file, each row paired with its 1-based line number.

    Raises:
        BadInputError: wrong header, an empty drive, a bad frame number, a non-finite coordinate, a bad
            station or enabled value, or a drive and frame grounded twice.
    """
    _, rows = read_table(text, file, [CONTROL_HEADER])
    out: list[tuple[int, SiteGroundingRow]] = []
    seen: dict[tuple[str, int], int] = {}
    for row in rows:
        cells, line = row.cells, row.line
        drive = parse_text(cells["drive"].strip(), file=file, line=line, field="drive")
        frame = parse_int(cells["frame"], file=file, line=line, field="frame")
        if frame < 0:
            raise BadInputError("a frame number is 0 or more", file=file, line=line, field="frame")
        if (drive, frame) in seen:
            raise BadInputError(
                f"frame {frame} of drive {drive!r} is grounded twice (first on line {seen[drive, frame]})",
                file=file,
                line=line,
                field="frame",
            )
        seen[drive, frame] = line
        parsed = SiteGroundingRow(
            drive=drive,
            frame=frame,
            station=parse_station(cells["station"], file=file, line=line),
            x_m=parse_float(cells["x"], file=file, line=line, field="x"),
            y_m=parse_float(cells["y"], file=file, line=line, field="y"),
            enabled=parse_enabled(cells["enabled"], file=file, line=line),
        )
        out.append((line, parsed))
    return out


@dataclass(frozen=True)
class ResidualCsvRow:
    """One row of a map version's residuals CSV."""

    drive: str
    frame: int
    station: str | None
    x_m: float
    y_m: float
    """Surveyed position the build used, metres (survey frame)."""
    residual_m: float
    """Distance from the optimised pose to the surveyed point, metres."""
    enabled: bool | None
    """Whether the grounding is enabled now; None when it has been deleted since the build."""


def residuals_text(rows: Iterable[ResidualCsvRow]) -> str:
    """The residuals CSV: header ``drive,frame,station,x,y,residual_m,enabled``."""
    return table_text(
        RESIDUALS_HEADER,
        (
            [
                r.drive,
                str(int(r.frame)),
                r.station or "",
                format_float(r.x_m, field="x"),
                format_float(r.y_m, field="y"),
                format_optional_float(r.residual_m, field="residual_m"),
                "" if r.enabled is None else format_enabled(r.enabled),
            ]
            for r in rows
        ),
    )
