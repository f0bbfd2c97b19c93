"""Shared fixtures: real SQLite files with migrations applied, a real blob store."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from driftmap.config import Settings
from driftmap.store.storage import Storage

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


@pytest.fixture
def settings(tmp_path: Path) -> Settings:
    """Settings pointing at a fresh data directory (SQLite file + blob store)."""
    return Settings(data_dir=tmp_path / "data")


@pytest.fixture
def storage(settings: Settings) -> Iterator[Storage]:
    """A migrated SQLite database and an empty blob store."""
    opened = Storage.open(settings)
    yield opened
    opened.close()
