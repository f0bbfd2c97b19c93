"""The tiny simulated site with its localisation drive imported and one FAST map built, once per session.

Tests of localisation only read this store (they write their outputs elsewhere), so one build serves the
service, report and CLI tests. On a PostgreSQL run its rows live in a database of their own that outlives
each test (the per-test databases are dropped), named by the returned settings.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from driftmap.config import Settings
from driftmap.core.mapping.pipeline import MAPPING_FAST
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.store.storage import Storage
from tests.postgres_server import active_server
from tests.sim_site import import_site

SITE = "tiny"
_BUILT: dict[Path, Settings] = {}


def tiny_map_settings(tmp_path_factory: pytest.TempPathFactory, site_dir: Path) -> Settings:
    """Settings of a store holding the tiny site (mapping + localisation drives) and map version 1 (FAST)."""
    if site_dir not in _BUILT:
        server = active_server()
        settings = Settings(
            data_dir=tmp_path_factory.mktemp("tiny-map") / "data",
            database_url=None if server is None else server.snapshot()[1],  # None: the SQLite file
        )
        storage = Storage.open(settings)
        try:
            import_site(storage, site_dir, SITE, kinds=("mapping", "localisation"))
            with storage.blobs.batch() as batch, storage.db.session() as session:
                site = site_service.get_site(session, SITE)
                map_service.build_site_map(session, storage.blobs, batch, site, MAPPING_FAST)
        finally:
            storage.close()
        _BUILT[site_dir] = settings
    return _BUILT[site_dir]


def loc_drive_dir(site_dir: Path) -> Path:
    """The tiny site's first localisation drive folder."""
    return sorted(p for p in (site_dir / "drives").iterdir() if p.name.startswith("loc"))[0]
