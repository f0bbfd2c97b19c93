"""The tiny simulated site with one FAST map built and its localisation drives imported, once per session.

The map is the one the API tests copy (:func:`tests.api.access_helpers.built_tiny_data`, mapping drives only):
its data directory is copied once and the localisation drives are imported into the copy, so the session
builds the tiny map once. Tests of localisation only read this store (they write their outputs elsewhere), so
one copy serves the service, report and CLI tests. On a PostgreSQL run its rows live in a database of their
own that outlives each test (the per-test databases are dropped), named by the returned settings.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from driftmap.config import Settings
from driftmap.store.storage import Storage
from tests.api.access_helpers import built_tiny_data, copy_data_to_new_database
from tests.sim_site import import_drives

SITE = "tiny"
_BUILT: dict[Path, Settings] = {}


def tiny_map_settings(tmp_path_factory: pytest.TempPathFactory, site_dir: Path) -> Settings:
    """Settings of a store holding the tiny site (mapping + localisation drives) and map version 1 (FAST)."""
    if site_dir not in _BUILT:
        data, database_url = copy_data_to_new_database(
            built_tiny_data(tmp_path_factory.getbasetemp(), site_dir),
            tmp_path_factory.mktemp("tiny-map") / "data",
        )
        settings = Settings(data_dir=data, database_url=database_url)  # None: the copied SQLite file
        storage = Storage.open(settings)
        try:
            import_drives(storage, site_dir, SITE, kinds=("localisation",))
        finally:
            storage.close()
        _BUILT[site_dir] = settings
    return _BUILT[site_dir]


def loc_drive_dir(site_dir: Path) -> Path:
    """The tiny site's first localisation drive folder."""
    return sorted(p for p in (site_dir / "drives").iterdir() if p.name.startswith("loc"))[0]
