"""Ranges of input values that driftmap can store and compute with: integers, timestamps, image sizes.

The database holds ids, frame numbers and counters in 32 bits (PostgreSQL ``integer``; SQLite's ``INTEGER``
holds more, the limit is the same on both), other integers in 64 bits and times as float64 seconds; a value
outside these ranges would fail deep inside a driver (a server error) or poison later arithmetic (an infinite
duration, a speed of NaN). Every reader of user input checks against the limits
here and names the field at fault.
"""

from __future__ import annotations

import math
from pathlib import Path

from driftmap.errors import BadInputError

INT64_MIN = -(2**63)
INT64_MAX = 2**63 - 1
DB_INT_MIN = -(2**31)
DB_INT_MAX = 2**31 - 1
"""The range of a stored id, frame number or counter (PostgreSQL ``integer``)."""
MAX_ABS_T_S = 1e10
"""Largest timestamp magnitude, seconds (about 317 years: Unix time in seconds fits, nanoseconds do not)."""
MAX_CAMERA_SIDE_PX = 16384
"""Largest camera width or height, pixels (a camera block asking for more is refused)."""


def check_t_s(
    t_s: float, field: str = "t", *, file: str | Path | None = None, line: int | None = None
) -> float:
    """Check a timestamp is a finite number of seconds within ``MAX_ABS_T_S`` of zero.

    Args:
        t_s: the timestamp, seconds.
        field: the name of the field it came from, for the error message.
        file: the file it came from, if any.
        line: the 1-based line of ``file``, if any.

    Returns:
        ``t_s`` as a float.

    Raises:
        BadInputError: NaN, infinite or too large, naming ``field``.
    """
    value = float(t_s)
    if not math.isfinite(value) or abs(value) > MAX_ABS_T_S:
        raise BadInputError(
            f"must be a finite number of seconds within ±{MAX_ABS_T_S:g}, got {value!r}",
            field=field,
            file=file,
            line=line,
        )
    return value


def check_db_int(value: int, field: str, *, file: str | Path | None = None, line: int | None = None) -> int:
    """Check an integer fits the database's integer columns (ids, frame numbers, counters).

    Raises:
        BadInputError: outside ``[DB_INT_MIN, DB_INT_MAX]``, naming ``field`` (and ``file``, ``line``).
    """
    if not DB_INT_MIN <= value <= DB_INT_MAX:
        raise BadInputError(
            f"must be a 32-bit integer ({DB_INT_MIN} to {DB_INT_MAX})", field=field, file=file, line=line
        )
    return value
