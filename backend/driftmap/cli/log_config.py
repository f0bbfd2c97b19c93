"""The server's logging: uvicorn's handlers with query strings removed from every logged URL.

Query strings can carry secrets a client should not have put there (a ``?token=``, which the API refuses
anyway), and access logs are kept and shared; so the access log and uvicorn's WebSocket lines (``"WebSocket
/api/live?..." [accepted]``) show paths only. :func:`log_config` is uvicorn's own default configuration with
:class:`NoQueryStrings` on both of its handlers, so it applies to every API process ``driftmap serve``
starts.
"""

from __future__ import annotations

import copy
import logging
import re
from typing import Any

from driftmap.config import Settings

_QUERY = re.compile(r"(/[^\s?\"]*)\?[^\s\"]*")
"""A path followed by a query string, inside a longer text."""


def strip_query(text: str) -> str:
    """``text`` with the query string of every path in it removed (``/a?b=1 x`` -> ``/a x``)."""
    return _QUERY.sub(r"\1", text)


class NoQueryStrings(logging.Filter):
    """Removes query strings from the arguments and the message of every record (never drops one)."""

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.args, tuple):
            record.args = tuple(strip_query(a) if isinstance(a, str) else a for a in record.args)
        elif isinstance(record.args, dict):
            record.args = {k: strip_query(v) if isinstance(v, str) else v for k, v in record.args.items()}
        if isinstance(record.msg, str):
            record.msg = strip_query(record.msg)
        return True


def log_config(settings: Settings | None = None) -> dict[str, Any]:
    """uvicorn's default ``log_config`` with :class:`NoQueryStrings` and the request id
    (:class:`driftmap.logs.RequestIdFilter`) on its ``default`` and ``access`` handlers; with ``settings``, its
    loggers at ``log_level`` (INFO by default) and JSON lines when ``log_format`` is ``json``."""
    from uvicorn.config import LOGGING_CONFIG

    config: dict[str, Any] = copy.deepcopy(LOGGING_CONFIG)
    filters = config.setdefault("filters", {})
    filters["no_query_strings"] = {"()": f"{__name__}.NoQueryStrings"}
    filters["request_id"] = {"()": "driftmap.logs.RequestIdFilter"}
    for handler in config["handlers"].values():
        handler.setdefault("filters", []).extend(["no_query_strings", "request_id"])
    if settings is not None:
        level = settings.log_level or "INFO"
        for logger in config["loggers"].values():
            logger["level"] = level
        if settings.log_format == "json":
            for name in ("default", "access"):
                config["formatters"][name] = {"()": "driftmap.logs.JsonFormatter"}
    return config
