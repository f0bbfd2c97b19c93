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


@pytest.fixture(scope="session")
def tiny_site_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny simulated site, written once per test session (read-only for tests)."""
    from tests.sim_site import make_tiny_site

    return make_tiny_site(tmp_path_factory.mktemp("tiny-site") / "site")


@pytest.fixture(scope="session")
def small_site_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The small simulated site (seed 7, obscured copies included), written once per test session."""
    from driftmap.sim import simulate_site

    out = tmp_path_factory.mktemp("small-site") / "site"
    simulate_site(out, seed=7, size="small")
    return out
