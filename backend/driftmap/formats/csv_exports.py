"""The CSV files driftmap writes and reads besides ``frames.csv`` (``docs/formats.md``).

Each table has a ``*_text`` serialiser, a ``write_*`` that writes atomically, and a ``parse_*``/``read_*``
pair that validates (header, cell count, types, finite numbers) and raises :class:`BadInputError`
naming the file, the 1-based line (the header is line 1) and the column. Floats are written with
:func:`repr` so that reading gives back the identical float.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from driftmap.errors import BadInputError
from driftmap.formats.control_csv import format_enabled, parse_enabled, parse_station
from driftmap.formats.records import GroundingRow
from driftmap.formats.tables import (
    decode_text,
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

GROUNDINGS_HEADER: tuple[str, ...] = ("frame", "x", "y")
GROUNDINGS_CONTROL_HEADER: tuple[str, ...] = ("frame", "x", "y", "station", "enabled")
GROUNDINGS_HEADERS: tuple[tuple[str, ...], ...] = (
    GROUNDINGS_HEADER,
    GROUNDINGS_CONTROL_HEADER,
    ("frame", "x", "y", "station"),
    ("frame", "x", "y", "enabled"),
)


# ---------------------------------------------------------------------------------------------- groundings


def groundings_text(rows: Iterable[GroundingRow]) -> str:
    """``groundings.csv`` text, positions in metres (survey frame).

    The header is ``frame,x,y`` when no row names a station or is disabled, else
    ``frame,x,y,station,enabled``.
    """
    rows = list(rows)
    if all(r.station is None and r.enabled for r in rows):
        return table_text(
            GROUNDINGS_HEADER,
            (
                [str(int(r.frame)), format_float(r.x_m, field="x"), format_float(r.y_m, field="y")]
                for r in rows
            ),
        )
    return table_text(
        GROUNDINGS_CONTROL_HEADER,
        (
            [
                str(int(r.frame)),
                format_float(r.x_m, field="x"),
                format_float(r.y_m, field="y"),
                r.station or "",
                format_enabled(r.enabled),
            ]
            for r in rows
        ),
    )


def write_groundings_csv(path: Path, rows: Iterable[GroundingRow]) -> None:
    """Write ``groundings.csv`` atomically."""
    write_text_atomic(path, groundings_text(rows))


def parse_groundings_csv(text: str, file: str | Path) -> list[GroundingRow]:
    """Parse ``groundings.csv`` text (``frame,x,y`` with optional ``station`` and ``enabled`` columns); a
    frame may be grounded only once.

    Raises:
        BadInputError: wrong header, bad cells, a non-finite number, a duplicate frame.
    """
    return [row for _, row in parse_groundings_rows(text, file)]


def parse_groundings_rows(text: str, file: str | Path) -> list[tuple[int, GroundingRow]]:
    """:func:`parse_groundings_csv`, each row paired with its 1-based line number."""
    _, rows = read_table(text, file, GROUNDINGS_HEADERS)
    out: list[tuple[int, GroundingRow]] = []
    seen: dict[int, int] = {}
    for row in rows:
        frame = parse_int(row.cells["frame"], file=file, line=row.line, field="frame")
        if frame in seen:
            raise BadInputError(
                f"frame {frame} is grounded twice (first on line {seen[frame]})",
                file=file,
                line=row.line,
                field="frame",
            )
        seen[frame] = row.line
        x = parse_float(row.cells["x"], file=file, line=row.line, field="x")
        y = parse_float(row.cells["y"], file=file, line=row.line, field="y")
        station = parse_station(row.cells.get("station", ""), file=file, line=row.line)
        enabled = parse_enabled(row.cells.get("enabled", ""), file=file, line=row.line)
        out.append((row.line, GroundingRow(frame=frame, x_m=x, y_m=y, station=station, enabled=enabled)))
    return out


def read_groundings_csv(path: Path) -> list[GroundingRow]:
    """Read and validate a ``groundings.csv`` file."""
    return parse_groundings_csv(decode_text(Path(path).read_bytes(), path), path)


# ---------------------------------------------------------------------------------------------- map poses


@dataclass(frozen=True)
class PoseRow:
    """One row of the map poses export: a mapping-drive frame's pose in the survey frame.

    ``x_m, y_m`` is the floor point under the camera (metres), ``yaw_rad`` the heading counter-clockwise
    from +x (radians); ``t_s`` the frame's time, seconds since the drive's start (None when not carried).
    """

    drive: str
    frame: int
    x_m: float
    y_m: float
    yaw_rad: float
    t_s: float | None = None


POSES_HEADER: tuple[str, ...] = ("drive", "frame", "x", "y", "yaw")
#: the header of ``map export --format csv``: the poses with each frame's time
TIMED_POSES_HEADER: tuple[str, ...] = ("drive", "frame", "t", "x", "y", "yaw")


def poses_text(rows: Iterable[PoseRow], *, with_time: bool = False) -> str:
    """Poses CSV text, header ``drive,frame,x,y,yaw`` or, ``with_time``, ``drive,frame,t,x,y,yaw``."""

    def cells(r: PoseRow) -> list[str]:
        timed = [format_float(_time(r), field="t")] if with_time else []
        return [
            _name(r.drive, "drive"),
            str(int(r.frame)),
            *timed,
            format_float(r.x_m, field="x"),
            format_float(r.y_m, field="y"),
            format_float(r.yaw_rad, field="yaw"),
        ]

    return table_text(TIMED_POSES_HEADER if with_time else POSES_HEADER, (cells(r) for r in rows))


def _time(row: PoseRow) -> float:
    if row.t_s is None:
        raise ValueError(f"drive {row.drive!r} frame {row.frame} has no time t")
    return row.t_s


def write_poses_csv(path: Path, rows: Iterable[PoseRow], *, with_time: bool = False) -> None:
    """Write the poses CSV atomically (:func:`poses_text`)."""
    write_text_atomic(path, poses_text(rows, with_time=with_time))


def parse_poses_csv(text: str, file: str | Path) -> list[PoseRow]:
    """Parse poses CSV text, with or without the ``t`` column; each (drive, frame) may appear once."""
    header, table = read_table(text, file, [POSES_HEADER, TIMED_POSES_HEADER])
    out: list[PoseRow] = []
    seen: set[tuple[str, int]] = set()
    for row in table:
        cells, line = row.cells, row.line
        drive = parse_text(cells["drive"], file=file, line=line, field="drive")
        frame = parse_int(cells["frame"], file=file, line=line, field="frame")
        if (drive, frame) in seen:
            raise BadInputError(
                f"drive {drive!r} frame {frame} appears twice", file=file, line=line, field="frame"
            )
        seen.add((drive, frame))
        x, y, yaw = (parse_float(cells[k], file=file, line=line, field=k) for k in ("x", "y", "yaw"))
        t = parse_float(cells["t"], file=file, line=line, field="t") if "t" in header else None
        out.append(PoseRow(drive, frame, x, y, yaw, t))
    return out


def read_poses_csv(path: Path) -> list[PoseRow]:
    """Read and validate a poses CSV file."""
    return parse_poses_csv(decode_text(Path(path).read_bytes(), path), path)


# ---------------------------------------------------------------------------------------------- localisation


@dataclass(frozen=True)
class LocalisationRow:
    """One row of a localisation export: the position estimate of a query frame.

    ``node`` is the best node id b(i); ``x_m, y_m`` the vehicle's position (metres, survey frame; the
    continuous track along the mapped tunnels); ``score`` the confidence that the position is right, a
    calibrated probability in [0, 1]; ``matched`` whether it reached the configured threshold (and the
    localiser was not lost); ``yaw_rad`` the heading (radians counter-clockwise from +x) and ``speed_mps``
    the signed odometry speed, None when unknown; ``odometry`` whether the camera's odometry was used;
    ``x_paper`` the paper's X_i(b(i)) (eq. 11), None when not given.
    """

    frame: int
    node: int
    x_m: float
    y_m: float
    score: float
    matched: bool
    yaw_rad: float | None = None
    speed_mps: float | None = None
    odometry: bool = False
    x_paper: float | None = None


LOCALISATION_HEADER: tuple[str, ...] = (
    "frame", "node", "x", "y", "score", "matched", "yaw", "speed", "odometry", "x_paper"
)  # fmt: skip
#: the header before heading, speed, odometry and the paper's X were added; still read
LOCALISATION_HEADER_V1: tuple[str, ...] = ("frame", "node", "x", "y", "score", "matched")


def localisation_text(rows: Iterable[LocalisationRow]) -> str:
    """Localisation CSV text, header :data:`LOCALISATION_HEADER`; matched and odometry are 1 or 0, an unknown
    yaw, speed or x_paper an empty cell."""
    return table_text(
        LOCALISATION_HEADER,
        (
            [
                str(int(r.frame)),
                str(int(r.node)),
                format_float(r.x_m, field="x"),
                format_float(r.y_m, field="y"),
                format_float(r.score, field="score"),
                "1" if r.matched else "0",
                format_optional_float(r.yaw_rad, field="yaw"),
                format_optional_float(r.speed_mps, field="speed"),
                "1" if r.odometry else "0",
                format_optional_float(r.x_paper, field="x_paper"),
            ]
            for r in rows
        ),
    )


def write_localisation_csv(path: Path, rows: Iterable[LocalisationRow]) -> None:
    """Write the localisation CSV atomically."""
    write_text_atomic(path, localisation_text(rows))


def parse_localisation_csv(text: str, file: str | Path) -> list[LocalisationRow]:
    """Parse localisation CSV text; each frame may appear once, ``matched`` must be 0 or 1."""
    header, table = read_table(text, file, [LOCALISATION_HEADER, LOCALISATION_HEADER_V1])
    out: list[LocalisationRow] = []
    seen: set[int] = set()
    for row in table:
        cells, line = row.cells, row.line
        frame = parse_int(cells["frame"], file=file, line=line, field="frame")
        if frame in seen:
            raise BadInputError(f"frame {frame} appears twice", file=file, line=line, field="frame")
        seen.add(frame)
        node = parse_int(cells["node"], file=file, line=line, field="node")
        x, y, score = (parse_float(cells[k], file=file, line=line, field=k) for k in ("x", "y", "score"))
        for flag in ("matched", "odometry") if header == LOCALISATION_HEADER else ("matched",):
            if cells[flag] not in ("0", "1"):
                raise BadInputError(
                    f"must be 0 or 1, found {cells[flag][:20]!r}", file=file, line=line, field=flag
                )
        extra: dict[str, float | None] = {
            k: parse_optional_float(cells[k], file=file, line=line, field=k) if k in cells else None
            for k in ("yaw", "speed", "x_paper")
        }
        odometry = cells.get("odometry") == "1"
        out.append(
            LocalisationRow(
                frame,
                node,
                x,
                y,
                score,
                cells["matched"] == "1",
                extra["yaw"],
                extra["speed"],
                odometry,
                extra["x_paper"],
            )
        )
    return out


def read_localisation_csv(path: Path) -> list[LocalisationRow]:
    """Read and validate a localisation CSV file."""
    return parse_localisation_csv(decode_text(Path(path).read_bytes(), path), path)


# ---------------------------------------------------------------------------------------------- place recognition


@dataclass(frozen=True)
class PlaceMatchRow:
    """One row of a place-recognition export: the best reference image for a query image.

    ``query`` and ``db`` are file names; ``score`` a similarity, higher = more similar (e.g. negative SAD).
    """

    query: str
    db: str
    score: float


PLACE_HEADER: tuple[str, ...] = ("query", "db", "score")


def place_matches_text(rows: Iterable[PlaceMatchRow]) -> str:
    """Place-recognition CSV text, header ``query,db,score``."""
    return table_text(
        PLACE_HEADER,
        ([_name(r.query, "query"), _name(r.db, "db"), format_float(r.score, field="score")] for r in rows),
    )


def write_place_matches_csv(path: Path, rows: Iterable[PlaceMatchRow]) -> None:
    """Write the place-recognition CSV atomically."""
    write_text_atomic(path, place_matches_text(rows))


def parse_place_matches_csv(text: str, file: str | Path) -> list[PlaceMatchRow]:
    """Parse place-recognition CSV text; each query may appear once."""
    _, table = read_table(text, file, [PLACE_HEADER])
    out: list[PlaceMatchRow] = []
    seen: set[str] = set()
    for row in table:
        cells, line = row.cells, row.line
        query = parse_text(cells["query"], file=file, line=line, field="query")
        if query in seen:
            raise BadInputError(f"query {query!r} appears twice", file=file, line=line, field="query")
        seen.add(query)
        db = parse_text(cells["db"], file=file, line=line, field="db")
        score = parse_float(cells["score"], file=file, line=line, field="score")
        out.append(PlaceMatchRow(query, db, score))
    return out


def read_place_matches_csv(path: Path) -> list[PlaceMatchRow]:
    """Read and validate a place-recognition CSV file."""
    return parse_place_matches_csv(decode_text(Path(path).read_bytes(), path), path)


def _name(value: str, field: str) -> str:
    """A name cell as written: non-empty, one line, no surrounding blanks (which readers strip)."""
    if not value or value != value.strip() or "\n" in value or "\r" in value:
        raise ValueError(f"{field} {value!r} cannot be written as a CSV cell (empty, padded or multi-line)")
    return value
