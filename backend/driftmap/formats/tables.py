"""Small CSV tables with a fixed header, as every driftmap CSV is (``docs/formats.md``).

Reading keeps 1-based line numbers (the header is line 1) so that every error names the file, the line
and the column. Numbers are parsed strictly: decimal notation only, finite values only (no ``nan``,
``inf`` or ``1_000``). Floats are written with :func:`repr`, the shortest text that reads back as the
identical float.
"""

from __future__ import annotations

import csv
import io
import math
import os
import re
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from driftmap.errors import BadInputError

_INT_RE = re.compile(r"[+-]?[0-9]+")
_FLOAT_RE = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


@dataclass(frozen=True)
class CsvRow:
    """One data row of a CSV table.

    Attributes:
        line: 1-based line number in the file (the header is line 1).
        cells: column name -> cell text, whitespace stripped.
    """

    line: int
    cells: dict[str, str]


def decode_text(data: bytes, file: str | Path) -> str:
    """Decode UTF-8 text (a leading byte-order mark is dropped), naming the line of a bad byte."""
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data.count(b"\n", 0, exc.start) + 1
        raise BadInputError(f"not UTF-8 text (byte {exc.start})", file=file, line=line) from None


def read_table(
    text: str, file: str | Path, headers: Sequence[Sequence[str]]
) -> tuple[tuple[str, ...], list[CsvRow]]:
    """Split CSV text into rows keyed by column name, checking the header.

    Blank lines are skipped; every other line must have exactly as many cells as the header.

    Args:
        text: the whole file as text.
        file: the file name used in error messages.
        headers: the accepted headers, each a sequence of column names; the first is the preferred one.

    Returns:
        The header found (one of ``headers``) and the data rows in file order.

    Raises:
        BadInputError: a missing or wrong header, a row with the wrong number of cells, broken quoting.
    """
    lines = text.split("\n")
    if not lines or not lines[0].strip():
        raise BadInputError(
            f"missing header, expected '{','.join(headers[0])}'", file=file, line=1, field="header"
        )
    found = tuple(c.strip() for c in _split_line(lines[0].rstrip("\r"), file, 1))
    accepted = [tuple(h) for h in headers]
    if found not in accepted:
        wanted = " or ".join(f"'{','.join(h)}'" for h in accepted)
        # the header the file meant: the longest shared start, then the longest header
        best = max(accepted, key=lambda h: (_shared_start(found, h), len(h)))
        if len(found) > len(best) and found[: len(best)] == best:
            bad_field = found[len(best)]
        else:
            bad_field = next(
                (b for a, b in zip(found, best, strict=False) if a != b), best[min(len(found), len(best) - 1)]
            )
        raise BadInputError(
            f"header must be {wanted}, found '{','.join(found)}'", file=file, line=1, field=bad_field
        )
    rows: list[CsvRow] = []
    for index, raw in enumerate(lines[1:], start=2):
        line = raw.rstrip("\r")
        if not line.strip():
            continue
        cells = [c.strip() for c in _split_line(line, file, index)]
        if len(cells) != len(found):
            field = found[len(cells)] if len(cells) < len(found) else "(extra)"
            raise BadInputError(
                f"expected {len(found)} cells ({','.join(found)}), found {len(cells)}",
                file=file,
                line=index,
                field=field,
            )
        rows.append(CsvRow(index, dict(zip(found, cells, strict=True))))
    return found, rows


def _shared_start(a: Sequence[str], b: Sequence[str]) -> int:
    """How many leading column names ``a`` and ``b`` share."""
    n = 0
    while n < min(len(a), len(b)) and a[n] == b[n]:
        n += 1
    return n


def _split_line(line: str, file: str | Path, index: int) -> list[str]:
    if '"' not in line:
        return line.split(",")
    try:
        return next(csv.reader([line], strict=True))
    except (csv.Error, StopIteration) as exc:
        raise BadInputError(f"bad CSV quoting: {exc}", file=file, line=index) from None


def parse_int(text: str, *, file: str | Path, line: int, field: str) -> int:
    """Parse a decimal integer cell, raising :class:`BadInputError` naming file, line and field."""
    if not _INT_RE.fullmatch(text):
        raise BadInputError(f"'{_clip(text)}' is not an integer", file=file, line=line, field=field)
    return int(text)


def parse_float(text: str, *, file: str | Path, line: int, field: str) -> float:
    """Parse a finite decimal number cell, raising :class:`BadInputError` naming file, line and field."""
    if not _FLOAT_RE.fullmatch(text):
        raise BadInputError(f"'{_clip(text)}' is not a finite number", file=file, line=line, field=field)
    value = float(text)
    if not math.isfinite(value):
        raise BadInputError(f"'{_clip(text)}' is not a finite number", file=file, line=line, field=field)
    return value


def parse_optional_float(text: str, *, file: str | Path, line: int, field: str) -> float | None:
    """Like :func:`parse_float`, but an empty cell gives None."""
    return None if text == "" else parse_float(text, file=file, line=line, field=field)


def parse_text(text: str, *, file: str | Path, line: int, field: str) -> str:
    """A non-empty text cell (a name), raising :class:`BadInputError` when it is empty."""
    if not text:
        raise BadInputError("empty value", file=file, line=line, field=field)
    return text


def format_float(value: float, *, field: str = "value") -> str:
    """The shortest text that reads back as exactly ``value``; refuses NaN and infinities."""
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{field} must be finite, got {value!r}")
    return repr(value)


def format_optional_float(value: float | None, *, field: str = "value") -> str:
    """:func:`format_float`, or an empty cell for None."""
    return "" if value is None else format_float(value, field=field)


def table_text(header: Sequence[str], rows: Iterable[Sequence[str]]) -> str:
    """CSV text with ``\\n`` line ends; cells holding commas or quotes are quoted."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(header)
    writer.writerows(rows)
    return buffer.getvalue()


def write_text_atomic(path: Path, text: str) -> None:
    """Write ``text`` as UTF-8 to ``path`` through a temporary sibling and a rename."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as handle:
            handle.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _clip(text: str, limit: int = 40) -> str:
    return text if len(text) <= limit else text[: limit - 3] + "..."
