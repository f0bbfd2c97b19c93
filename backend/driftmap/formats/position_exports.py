"""Vehicle position history as a CSV file (``docs/formats.md``), and as tracks for the other exports.

A :class:`PositionRow` is one stored localisation estimate of a live vehicle: ``t`` on the vehicle's clock
(seconds), the position in the site plane (x east, y north, metres) and the localiser's verdict. The CSV
reads back with :func:`parse_positions_csv`, which validates it as every driftmap CSV is validated.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from driftmap.errors import BadInputError
from driftmap.formats.tables import (
    format_float,
    format_optional_float,
    parse_float,
    parse_int,
    parse_optional_float,
    parse_text,
    read_table,
    table_text,
    write_text_atomic,
)
from driftmap.formats.trajectory_exports import Track, TrackPose

POSITIONS_HEADER: tuple[str, ...] = (
    "vehicle", "t", "x", "y", "yaw", "node", "confidence", "matched", "lost", "speed"
)  # fmt: skip


@dataclass(frozen=True)
class PositionRow:
    """One position of one vehicle.

    ``t_s`` is the frame time on the vehicle's clock, seconds; ``x_m, y_m`` the floor point under the
    camera, site plane metres; ``yaw_rad`` the heading (radians counter-clockwise from +x) and
    ``speed_mps`` the signed odometry speed (metres per second, negative reversing), None when unknown;
    ``node`` the topological node; ``confidence`` the calibrated probability (0-1) that the position is
    right; ``matched`` whether it reached the threshold; ``lost`` whether the localiser was lost.
    """

    vehicle: str
    t_s: float
    x_m: float
    y_m: float
    yaw_rad: float | None
    node: int
    confidence: float
    matched: bool
    lost: bool
    speed_mps: float | None = None


def positions_text(rows: Iterable[PositionRow]) -> str:
    """Positions CSV text, header ``vehicle,t,x,y,yaw,node,confidence,matched,lost,speed``."""
    return table_text(
        POSITIONS_HEADER,
        (
            [
                _vehicle_cell(r.vehicle),
                format_float(r.t_s, field="t"),
                format_float(r.x_m, field="x"),
                format_float(r.y_m, field="y"),
                format_optional_float(r.yaw_rad, field="yaw"),
                str(int(r.node)),
                format_float(r.confidence, field="confidence"),
                "1" if r.matched else "0",
                "1" if r.lost else "0",
                format_optional_float(r.speed_mps, field="speed"),
            ]
            for r in rows
        ),
    )


def _vehicle_cell(name: str) -> str:
    if not name or name != name.strip() or "\n" in name or "\r" in name:
        raise ValueError(f"vehicle {name!r} cannot be written as a CSV cell (empty, padded or multi-line)")
    return name


def write_positions_csv(path: Path, rows: Iterable[PositionRow]) -> None:
    """Write the positions CSV atomically."""
    write_text_atomic(path, positions_text(rows))


def parse_positions_csv(text: str, file: str | Path) -> list[PositionRow]:
    """Parse positions CSV text; flags must be 0 or 1, numbers finite.

    Raises:
        BadInputError: a wrong header or cell, naming the file, line and column.
    """
    _, table = read_table(text, file, [POSITIONS_HEADER])
    out: list[PositionRow] = []
    for row in table:
        cells, line = row.cells, row.line
        for flag in ("matched", "lost"):
            if cells[flag] not in ("0", "1"):
                raise BadInputError(
                    f"must be 0 or 1, found {cells[flag][:20]!r}", file=file, line=line, field=flag
                )
        t, x, y, confidence = (
            parse_float(cells[k], file=file, line=line, field=k) for k in ("t", "x", "y", "confidence")
        )
        out.append(
            PositionRow(
                vehicle=parse_text(cells["vehicle"], file=file, line=line, field="vehicle"),
                t_s=t,
                x_m=x,
                y_m=y,
                yaw_rad=parse_optional_float(cells["yaw"], file=file, line=line, field="yaw"),
                node=parse_int(cells["node"], file=file, line=line, field="node"),
                confidence=confidence,
                matched=cells["matched"] == "1",
                lost=cells["lost"] == "1",
                speed_mps=parse_optional_float(cells["speed"], file=file, line=line, field="speed"),
            )
        )
    return out


def tracks_from_positions(rows: Sequence[PositionRow]) -> list[Track]:
    """Positions (grouped by vehicle, each in ``t`` order) as one ``vehicle`` track per vehicle."""
    tracks: dict[str, list[TrackPose]] = {}
    for r in rows:
        tracks.setdefault(r.vehicle, []).append(TrackPose(r.t_s, r.x_m, r.y_m, r.yaw_rad))
    return [Track(name, "vehicle", tuple(poses)) for name, poses in tracks.items()]
