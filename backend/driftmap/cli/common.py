"""What every command shares: consoles, the user-error guard, ``--json`` output, progress bars, storage.

Exit codes: 0 done, 1 a :class:`~driftmap.errors.DriftmapError` (bad input, not found, conflict: one line on
stderr), 2 a usage error (Click's: an unknown option, a value outside its choices, options that do not go
together).
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from datetime import datetime
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.text import Text

from driftmap.config import get_settings
from driftmap.errors import BadInputError, DriftmapError
from driftmap.store.storage import Storage

# soft_wrap: a message is never broken into lines (a terminal wraps it; a file path stays whole for a pipe)
console = Console(soft_wrap=True)
err_console = Console(stderr=True, soft_wrap=True)


DOMAIN_ERROR_EXIT = 1
"""The exit code of a command refused with a DriftmapError."""
USAGE_ERROR_EXIT = 2
"""The exit code of a usage error (Click's own for an unknown option or a value outside its choices)."""

JsonOption = Annotated[
    bool, typer.Option("--json", help="Print one JSON document on stdout instead of tables and text.")
]


@contextmanager
def user_errors() -> Iterator[None]:
    """Print a DriftmapError as one clear line and exit 1, without a traceback.

    A :class:`BadInputError` whose ``field`` is an option (``--format``) is the command line's fault: a usage
    error, exit 2 as Click's own.
    """
    try:
        yield
    except BadInputError as exc:
        usage = exc.field is not None and exc.field.startswith("--")
        _refuse(exc, USAGE_ERROR_EXIT if usage else DOMAIN_ERROR_EXIT)
    except DriftmapError as exc:
        _refuse(exc, DOMAIN_ERROR_EXIT)


def _refuse(exc: DriftmapError, code: int) -> None:
    err_console.print(Text.assemble(("error: ", "bold red"), str(exc)), soft_wrap=True)
    raise typer.Exit(code) from None


def _plain(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        value = dataclasses.asdict(value)
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, datetime):
        return value.isoformat()
    return value


def print_json(document: Any) -> None:
    """Write ``document`` as one JSON document on stdout: dataclasses as objects, dates in ISO 8601,
    NaN and infinities as null, anything else unknown (a path) as its text."""
    sys.stdout.write(json.dumps(_plain(document), default=str, ensure_ascii=False, allow_nan=False) + "\n")
    sys.stdout.flush()


@contextmanager
def stage_progress(description: str) -> Iterator[Callable[[str, float], None]]:
    """A rich progress bar; yields ``report(stage, fraction)`` that moves it."""
    columns = (TextColumn("{task.description:<24}"), BarColumn(), TextColumn("{task.percentage:>3.0f}%"))
    with Progress(*columns, TimeElapsedColumn(), console=err_console) as progress:
        task = progress.add_task(description, total=1.0)

        def report(stage: str, fraction: float) -> None:
            progress.update(task, description=stage, completed=fraction)

        yield report


def open_storage() -> Storage:
    """The configured database (upgraded) and blob store."""
    return Storage.open(get_settings())
