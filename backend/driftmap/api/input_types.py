"""Bounded types of request fields, path and query parameters: ids, counts, timestamps and texts.

Every id, frame number or counter a client sends ends up in a 32-bit database column (PostgreSQL ``integer``),
any other stored integer in 64 bits and every timestamp in float64 arithmetic, so the request models and
routes use these types instead of bare ``int``, ``float`` and ``str``: a value
out of range is a 422 naming its field (``loc``), and the OpenAPI document states the ranges.
"""

from __future__ import annotations

from typing import Annotated

from annotated_types import Ge, Le
from pydantic import AllowInfNan, StringConstraints

from driftmap.formats.bounds import DB_INT_MAX, INT64_MAX, INT64_MIN, MAX_ABS_T_S, MAX_CAMERA_SIDE_PX
from driftmap.formats.records import STATION_MAX_CHARS
from driftmap.services.users import MAX_PASSWORD_LENGTH, MIN_PASSWORD_LENGTH

NAME_MAX_CHARS = 200
"""Longest name of a site, drive or vehicle, characters."""
DESCRIPTION_MAX_CHARS = 10_000
"""Longest description of a site, characters."""

Id = Annotated[int, Ge(1), Le(DB_INT_MAX)]
"""The id of a stored row (site, drive, vehicle, job, grounding, map version number)."""
Count = Annotated[int, Ge(0), Le(DB_INT_MAX)]
"""A non-negative number that is stored or compared with a stored one: a frame number, an offset, a position
``seq``."""
Int64 = Annotated[int, Ge(INT64_MIN), Le(INT64_MAX)]
"""Any integer that is stored (64 bits)."""
Seconds = Annotated[float, AllowInfNan(False), Ge(-MAX_ABS_T_S), Le(MAX_ABS_T_S)]
"""A timestamp, seconds: finite and within ``MAX_ABS_T_S`` of zero."""
Finite = Annotated[float, AllowInfNan(False)]
"""A finite number (no NaN, no infinity)."""
CameraSide = Annotated[int, Ge(1), Le(MAX_CAMERA_SIDE_PX)]
"""A camera's frame width or height, pixels."""
Name = Annotated[
    str, StringConstraints(min_length=1, max_length=NAME_MAX_CHARS, pattern=r"^[^\x00-\x1f\x7f]+$")
]
"""A non-empty name of at most ``NAME_MAX_CHARS`` characters, without control characters (line breaks)."""
Station = Annotated[str, StringConstraints(max_length=STATION_MAX_CHARS, pattern=r"^[^\x00-\x1f\x7f]*$")]
"""A survey station id of at most ``STATION_MAX_CHARS`` characters, without control characters."""
Description = Annotated[str, StringConstraints(max_length=DESCRIPTION_MAX_CHARS)]
"""A free-text description of at most ``DESCRIPTION_MAX_CHARS`` characters."""
Password = Annotated[str, StringConstraints(max_length=MAX_PASSWORD_LENGTH)]
"""A password as typed: at most ``MAX_PASSWORD_LENGTH`` characters."""
NewPassword = Annotated[
    str, StringConstraints(min_length=MIN_PASSWORD_LENGTH, max_length=MAX_PASSWORD_LENGTH)
]
"""A password being set: ``MIN_PASSWORD_LENGTH`` to ``MAX_PASSWORD_LENGTH`` characters, as the users service
checks (the OpenAPI document states both)."""
