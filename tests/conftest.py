"""Shared fixtures: real databases with migrations applied, a real blob store, the simulated sites.

The suite runs on the embedded SQLite default, or on PostgreSQL with ``--database postgresql`` (or
``DRIFTMAP_TEST_DATABASE=postgresql``): a private PostgreSQL server is started for the session and every test
marked ``db`` gets a fresh database through ``DRIFTMAP_DATABASE_URL``, which every ``Settings`` (in the test
and in the processes it starts) reads.

Which tests touch the database is decided here, not by hand: a test is marked ``db`` when it uses a database
fixture (:data:`DB_FIXTURES`) or lives where every test is about the server side (:data:`DB_PATHS`), and
``make test`` runs the ``db`` tests of the store, services, API, jobs and live on PostgreSQL. A test that is not marked ``db`` runs with a database URL and
a database server that fail on first use (:data:`UNMARKED_DATABASE_URL`), so one that reaches the database
another way fails on SQLite too instead of silently missing the PostgreSQL run.
"""

from __future__ import annotations

import os
from collections.abc import Generator, Iterator
from pathlib import Path
from typing import NoReturn, cast

import pytest
from argon2 import PasswordHasher

from driftmap.config import Settings, get_settings
from driftmap.services import security
from driftmap.store.storage import Storage
from tests.made_once import made_once
from tests.postgres_server import PostgresServer, active_server, postgres_bin_dir, set_active_server

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"
DATABASES = ("sqlite", "postgresql")
TESTS = Path(__file__).resolve().parent

DB_FIXTURES = frozenset({"settings", "storage", "postgres_server"})
"""A test that uses one of these (directly or through another fixture) is marked ``db``."""
DB_PATHS = (
    "api",
    "cli",
    "e2e",
    "jobs",
    "live",
    "services",
    "store",
    "topology",
    "test_cli.py",
    "test_serve.py",
)
"""Folders and files under tests/ whose every test is marked ``db`` (they open stores through helpers too)."""
UNMARKED_DATABASE_URL = "not_marked_db://a-test-that-opens-a-database-must-be-marked-db/see-tests-conftest"
"""``DRIFTMAP_DATABASE_URL`` while a test not marked ``db`` runs: opening it fails (no such dialect)."""


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


def touches_database(item: pytest.Item) -> bool:
    """Whether ``item`` uses a database fixture or lives under one of :data:`DB_PATHS`."""
    if DB_FIXTURES & set(getattr(item, "fixturenames", ())):
        return True
    try:
        relative = item.path.resolve().relative_to(TESTS).as_posix()
    except ValueError:  # a test file outside tests/
        return False
    return any(relative == p or relative.startswith(f"{p}/") for p in DB_PATHS)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        if touches_database(item):
            item.add_marker(pytest.mark.db)


class _NoDatabaseServer:
    """The "server" of a test not marked ``db``: any use fails and names the fix."""

    def __getattr__(self, name: str) -> NoReturn:
        raise AssertionError(
            f"a test not marked db used the run's database server (.{name}): mark it pytest.mark.db "
            "or use a database fixture (tests/conftest.py)"
        )


_run_server: PostgresServer | None = None
"""The PostgreSQL server of a ``--database postgresql`` run, once started."""


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(
    item: pytest.Item, nextitem: pytest.Item | None
) -> Generator[None, object, object]:
    """A test not marked ``db`` runs with a database URL and server that fail on first use."""
    if item.get_closest_marker("db") is not None:
        return (yield)
    saved = os.environ.get("DRIFTMAP_DATABASE_URL")
    os.environ["DRIFTMAP_DATABASE_URL"] = UNMARKED_DATABASE_URL
    set_active_server(cast(PostgresServer, _NoDatabaseServer()))
    get_settings.cache_clear()
    try:
        return (yield)
    finally:
        if saved is None:
            os.environ.pop("DRIFTMAP_DATABASE_URL", None)
        else:
            os.environ["DRIFTMAP_DATABASE_URL"] = saved
        set_active_server(_run_server)
        get_settings.cache_clear()


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


@pytest.fixture(scope="session", autouse=True)
def _run_database_server(request: pytest.FixtureRequest) -> Iterator[None]:
    """On PostgreSQL: the run's server is active from the first test on, module-scoped fixtures included."""
    global _run_server
    if not on_postgresql(request.config):
        yield
        return
    _run_server = request.getfixturevalue("postgres_server")
    if not isinstance(active_server(), _NoDatabaseServer):
        set_active_server(_run_server)
    yield
    _run_server = None
    set_active_server(None)


@pytest.fixture(autouse=True)
def _database_url(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """On PostgreSQL, for a test marked ``db``: a fresh migrated database, named by ``DRIFTMAP_DATABASE_URL``."""
    if not on_postgresql(request.config) or request.node.get_closest_marker("db") is None:
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

    return made_once(tmp_path_factory, "tiny-site", make_tiny_site)


@pytest.fixture(scope="session")
def small_site_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The small simulated site (seed 7), written once per test session. No obscured copies: its tests use the
    mapping drives, whose frames do not depend on them."""
    from driftmap.sim import simulate_site

    return made_once(
        tmp_path_factory, "small-site", lambda out: simulate_site(out, seed=7, size="small", obscurants=False)
    )


@pytest.fixture(scope="session")
def mini_site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The mini simulated site (the tiny site's first 100 frames per drive), made once per test session."""
    from tests.jobs.mini_site import mini_site_dir

    return mini_site_dir(tmp_path_factory)


@pytest.fixture(autouse=True, scope="session")
def _light_password_hashes() -> Iterator[None]:
    """Password hashes of the suite's own users at a light argon2id cost (one pass over 64 KiB).

    Most API tests create and log in a user of every role; at the product's cost (argon2-cffi's defaults: three
    passes over 64 MiB) that is about a second a test. The hashes stay argon2id PHC strings made and checked by
    the product's code; a hash made at the full cost (a ``driftmap user add`` process) is still verified at its
    own cost, which the string records.
    """
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(security, "_hasher", PasswordHasher(time_cost=1, memory_cost=64, parallelism=1))
        yield
