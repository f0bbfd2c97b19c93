"""Fixtures of the API tests: users of every role on the test's database, the mini site imported, a built
tiny site to copy.

``mini_site`` (the simulated site the data tests upload and import) is in tests/conftest.py.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from driftmap.config import Settings
from tests.api.access_helpers import Actors, built_tiny_data, copy_data, make_actors
from tests.api.data_helpers import ApiUsers, api_users
from tests.sim_site import import_site


@pytest.fixture
def built(tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path, tmp_path: Path) -> Path:
    """A private copy of a data dir holding the tiny site with a built map (its rows too on PostgreSQL)."""
    return copy_data(built_tiny_data(tmp_path_factory.getbasetemp(), tiny_site_dir), tmp_path / "data")


@pytest.fixture
def users(settings: Settings) -> Iterator[ApiUsers]:
    """An app on the test's database with a logged-in user of every role; jobs run in the request (immediate)."""
    made = api_users(settings)
    yield made
    made.client.close()


@pytest.fixture
def site_id(users: ApiUsers, mini_site: Path) -> int:
    """Site ``tiny``: the mini site's survey and its mapping and localisation drives, imported into the store."""
    import_site(users.storage, mini_site, name="tiny", kinds=("mapping", "localisation"))
    return int(users.get("/api/sites")["items"][0]["id"])


@pytest.fixture
def live_actors(built: Path) -> Iterator[Actors]:
    """Users of every role and two vehicles on a private copy of the built tiny site, one localiser process."""
    made = make_actors(Settings(data_dir=built, stale_after_s=3600.0, live_processes=1), site_name="tiny")
    with made.client:
        yield made
