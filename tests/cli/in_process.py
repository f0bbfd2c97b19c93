"""Running ``driftmap`` commands in the test process (typer's ``CliRunner``) against a prepared store."""

from __future__ import annotations

import pytest

from driftmap.config import Settings, get_settings


def point_cli_at(monkeypatch: pytest.MonkeyPatch, settings: Settings) -> None:
    """Make the next commands read ``settings``' data dir and database (the embedded SQLite file when it has
    no database URL), as a ``driftmap`` process started with them in its environment would."""
    monkeypatch.setenv("DRIFTMAP_DATA_DIR", str(settings.data_dir))
    if settings.database_url is None:
        monkeypatch.delenv("DRIFTMAP_DATABASE_URL", raising=False)
    else:
        monkeypatch.setenv("DRIFTMAP_DATABASE_URL", settings.database_url)
    get_settings.cache_clear()
