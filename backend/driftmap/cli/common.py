"""What every command shares: consoles, the user-error guard, progress bars, opening storage."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.text import Text

from driftmap.config import get_settings
from driftmap.errors import DriftmapError
from driftmap.store.storage import Storage

console = Console()
err_console = Console(stderr=True)


@contextmanager
def user_errors() -> Iterator[None]:
    """Print a DriftmapError as one clear line and exit 2, without a traceback."""
    try:
        yield
    except DriftmapError as exc:
        err_console.print(Text.assemble(("error: ", "bold red"), str(exc)), soft_wrap=True)
        raise typer.Exit(2) from None


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
