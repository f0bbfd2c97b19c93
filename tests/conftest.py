"""Shared fixtures: real databases with migrations applied, a real blob store.

The suite runs on the embedded SQLite default, or on PostgreSQL with ``--database postgresql`` (or
``DRIFTMAP_TEST_DATABASE=postgresql``): a private PostgreSQL server is started for the session and every test
gets a fresh database through ``DRIFTMAP_DATABASE_URL``, which every ``Settings`` (in the test and in the
processes it starts) reads.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest

from driftmap.config import Settings, get_settings
from driftmap.store.storage import Storage
from tests.postgres_server import PostgresServer, postgres_bin_dir, set_active_server

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
DATABASES = ("sqlite", "postgresql")


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--database",
        choices=DATABASES,
        default=os.environ.get("DRIFTMAP_TEST_DATABASE", "sqlite"),
        help="database the tests run on (default: $DRIFTMAP_TEST_DATABASE or sqlite)",
    )


def on_postgresql(config: pytest.Config) -> bool:
    """Whether this run puts the tests' databases on PostgreSQL."""
    return bool(config.getoption("--database") == "postgresql")


@pytest.fixture(scope="session")
def postgres_server() -> Iterator[PostgresServer]:
    """A private PostgreSQL server for the session (skipped when PostgreSQL is not installed)."""
    bin_dir = postgres_bin_dir()
    if bin_dir is None:
        pytest.skip("PostgreSQL is not installed (make test installs Debian's postgresql)")
    server = PostgresServer(bin_dir)
    try:
        server.start()
        server.prepare_template()
        yield server
    finally:
        server.stop()


@pytest.fixture(autouse=True)
def _database_url(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """On PostgreSQL: a fresh migrated database for this test, named by ``DRIFTMAP_DATABASE_URL``."""
    if not on_postgresql(request.config):
        yield
        return
    server: PostgresServer = request.getfixturevalue("postgres_server")
    set_active_server(server)
    name, url = server.fresh_database()
    monkeypatch.setenv("DRIFTMAP_DATABASE_URL", url)
    get_settings.cache_clear()
    try:
        yield
    finally:
        get_settings.cache_clear()
        server.drop_database(name)


@pytest.fixture
def settings(tmp_path: Path) -> Settings:
    """Settings pointing at a fresh data directory (blob store, and SQLite file unless on PostgreSQL)."""
    return Settings(data_dir=tmp_path / "data")


@pytest.fixture
def storage(settings: Settings) -> Iterator[Storage]:
    """A migrated database and an empty blob store."""
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
