"""The CSV files driftmap writes and reads besides ``frames.csv`` (``shared/formats.md``).

Each table has a ``*_text`` serialiser, a ``write_*`` that writes atomically, and a ``parse_*``/``read_*``
pair that validates (header, cell count, types, finite numbers) and raises :class:`BadInputError`
naming the file, the 1-based line (the header is line 1) and the column. Floats are written with
:func:`repr` so that reading gives back the identical float.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from driftmap.errors import BadInputError
from driftmap.formats.records import GroundingRow
from driftmap.formats.tables import (
    decode_text,
    format_float,
    parse_float,
    parse_int,
    read_table,
    table_text,
    write_text_atomic,
)

GROUNDINGS_HEADER: tuple[str, ...] = ("frame", "x", "y")


# ---------------------------------------------------------------------------------------------- groundings


def groundings_text(rows: Iterable[GroundingRow]) -> str:
    """``groundings.csv`` text: header ``frame,x,y``, positions in metres (survey frame)."""
    return table_text(
        GROUNDINGS_HEADER,
        ([str(int(r.frame)), format_float(r.x_m, field="x"), format_float(r.y_m, field="y")] for r in rows),
    )


def write_groundings_csv(path: Path, rows: Iterable[GroundingRow]) -> None:
    """Write ``groundings.csv`` atomically."""
    write_text_atomic(path, groundings_text(rows))


def parse_groundings_csv(text: str, file: str | Path) -> list[GroundingRow]:
    """Parse ``groundings.csv`` text; a frame may be grounded only once.

    Raises:
        BadInputError: wrong header, bad cells, a non-finite number, a duplicate frame.
    """
    return [row for _, row in parse_groundings_rows(text, file)]


def parse_groundings_rows(text: str, file: str | Path) -> list[tuple[int, GroundingRow]]:
    """:func:`parse_groundings_csv`, each row paired with its 1-based line number."""
    _, rows = read_table(text, file, [GROUNDINGS_HEADER])
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
        out.append((row.line, GroundingRow(frame=frame, x_m=x, y_m=y)))
    return out


def read_groundings_csv(path: Path) -> list[GroundingRow]:
    """Read and validate a ``groundings.csv`` file."""
    return parse_groundings_csv(decode_text(Path(path).read_bytes(), path), path)
