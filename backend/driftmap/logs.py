"""Log records for people and for log collectors: a level and a format from the settings, a request id.

``DRIFTMAP_LOG_LEVEL`` (``DEBUG``, ``INFO``, ``WARNING``, ``ERROR``; default INFO for ``driftmap serve`` and
``driftmap worker``, WARNING for other commands) and ``DRIFTMAP_LOG_FORMAT`` (``text``, or ``json``: one JSON
object per line with ``time`` (UTC, ISO 8601), ``level``, ``logger``, ``message``, ``request_id`` when the
record belongs to an HTTP request, and ``exc`` with the traceback). The API gives every request an id
(``X-Request-ID``: the client's when it sends a sane one, else a new one; echoed in the response), which
:class:`RequestIdFilter` puts on every record logged while the request is handled, the access log's line too.
"""

from __future__ import annotations

import json
import logging
import re
from contextvars import ContextVar
from datetime import UTC, datetime

__all__ = ["REQUEST_ID", "TEXT_FORMAT", "JsonFormatter", "RequestIdFilter", "sane_request_id"]

REQUEST_ID: ContextVar[str | None] = ContextVar("driftmap_request_id", default=None)
"""The id of the HTTP request being handled in this context (None outside one)."""

TEXT_FORMAT = "%(asctime)s %(levelname)s %(name)s: %(message)s"

_SANE = re.compile(r"[A-Za-z0-9._-]{1,64}")


def sane_request_id(value: str | None) -> str | None:
    """``value`` when it can be logged as a request id as it is (1-64 letters, digits, ``.``, ``_``, ``-``)."""
    return value if value is not None and _SANE.fullmatch(value) else None


class RequestIdFilter(logging.Filter):
    """Sets ``record.request_id`` from :data:`REQUEST_ID` (never drops a record)."""

    def filter(self, record: logging.LogRecord) -> bool:
        record.request_id = REQUEST_ID.get()
        return True


class JsonFormatter(logging.Formatter):
    """One JSON object per record (see the module doc)."""

    def format(self, record: logging.LogRecord) -> str:
        out: dict[str, object] = {
            "time": datetime.fromtimestamp(record.created, UTC).isoformat(timespec="milliseconds"),
            "level": record.levelname,
            "logger": record.name,
            "message": record.getMessage(),
        }
        request_id = getattr(record, "request_id", None) or REQUEST_ID.get()
        if request_id:
            out["request_id"] = request_id
        if record.exc_info:
            out["exc"] = self.formatException(record.exc_info)
        return json.dumps(out, ensure_ascii=False)
