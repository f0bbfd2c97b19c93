"""Fixtures of the CLI tests: the commands pointed at a private copy of the built tiny site."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from driftmap.config import Settings, get_settings
from tests.api.access_helpers import built_tiny_data, copy_data_to_new_database
from tests.cli.in_process import point_cli_at


@pytest.fixture
def built_tiny_cli(
    tmp_path_factory: pytest.TempPathFactory,
    tiny_site_dir: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> Iterator[None]:
    """The CLI pointed at a private copy of the built tiny site (the run's database kind), free to change."""
    data, url = copy_data_to_new_database(
        built_tiny_data(tmp_path_factory.getbasetemp(), tiny_site_dir), tmp_path / "data"
    )
    point_cli_at(monkeypatch, Settings(data_dir=data, database_url=url))
    yield
    get_settings.cache_clear()
