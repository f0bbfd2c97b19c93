"""The one error hierarchy of driftmap.

Every error a user can cause is a :class:`DriftmapError`. Messages name the file, line or field
at fault so that a person can fix the input; the API maps the subclasses to HTTP status codes
and the CLI prints them without a traceback.
"""

from __future__ import annotations

from pathlib import Path


class DriftmapError(Exception):
    """Base of every error driftmap raises on purpose."""


class BadInputError(DriftmapError):
    """Input that cannot be used: a malformed file, a bad value, a broken image.

    Args:
        message: what is wrong, in words a user understands.
        file: the file at fault, if any.
        line: 1-based line number inside ``file``, if known.
        field: the column, key or parameter at fault, if known.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | Path | None = None,
        line: int | None = None,
        field: str | None = None,
    ) -> None:
        self.reason = message
        self.file = str(file) if file is not None else None
        self.line = line
        self.field = field
        where = ""
        if self.file is not None:
            where = self.file if line is None else f"{self.file}:{line}"
        if field is not None:
            where = f"{where} field '{field}'" if where else f"field '{field}'"
        super().__init__(f"{where}: {message}" if where else message)


class NotFoundError(DriftmapError):
    """A named thing (site, drive, frame, map version) does not exist."""


class ConflictError(DriftmapError):
    """The request clashes with what is stored (a duplicate name, a stale version)."""


class PayloadTooLargeError(BadInputError):
    """An upload larger than the configured limit (HTTP 413)."""


class BadRequestError(BadInputError):
    """A request the server cannot read at all: wrong content type, missing body (HTTP 400).

    Plain :class:`BadInputError` means the request was read but its content is unusable (HTTP 422).
    """
