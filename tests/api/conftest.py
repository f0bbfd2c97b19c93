"""Fixtures of the API tests."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.api.access_helpers import built_tiny_data, copy_data


@pytest.fixture
def built(tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path, tmp_path: Path) -> Path:
    """A private copy of a data dir holding the tiny site with a built map (its rows too on PostgreSQL)."""
    return copy_data(built_tiny_data(tmp_path_factory.getbasetemp(), tiny_site_dir), tmp_path / "data")
