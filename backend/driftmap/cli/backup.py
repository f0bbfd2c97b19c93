"""``driftmap backup`` and ``driftmap restore``: the embedded installation's database, blobs and signing key."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from driftmap.cli.common import console, user_errors
from driftmap.config import get_settings
from driftmap.services import backup as backup_service


def backup(
    out: Annotated[Path, typer.Argument(help="The backup file to write (a new .tar file).")],
) -> None:
    """Back up the data dir (SQLite database, blobs, signing key) into one tar file, while serving."""
    with user_errors():
        summary = backup_service.backup(get_settings(), out)
    console.print(f"backed up {summary.describe()}")


def restore(
    archive: Annotated[Path, typer.Argument(help="A file written by `driftmap backup`.")],
) -> None:
    """Restore a backup into an empty data dir (DRIFTMAP_DATA_DIR); refuses to overwrite anything."""
    with user_errors():
        summary = backup_service.restore(get_settings(), archive)
    console.print(f"restored {summary.describe()} into {get_settings().data_dir}")
