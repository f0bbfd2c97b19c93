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


def log_config() -> dict[str, Any]:
    """uvicorn's default ``log_config`` with :class:`NoQueryStrings` on its ``default`` and ``access`` handlers."""
    from uvicorn.config import LOGGING_CONFIG

    config: dict[str, Any] = copy.deepcopy(LOGGING_CONFIG)
    config.setdefault("filters", {})["no_query_strings"] = {"()": f"{__name__}.NoQueryStrings"}
    for handler in config["handlers"].values():
        handler.setdefault("filters", []).append("no_query_strings")
    return config
