"""The tiny simulated site with its localisation drive imported and one FAST map built, once per session.

Tests of localisation only read this store (they write their outputs elsewhere), so one build serves the
service, report and CLI tests.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from driftmap.config import Settings
from driftmap.core.mapping import FAST
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.store.storage import Storage
from tests.sim_site import import_site

SITE = "tiny"
_BUILT: dict[Path, Path] = {}


def tiny_map_data_dir(tmp_path_factory: pytest.TempPathFactory, site_dir: Path) -> Path:
    """A data dir holding the tiny site (mapping + localisation drives) and map version 1 (FAST preset)."""
    if site_dir not in _BUILT:
        data_dir = tmp_path_factory.mktemp("tiny-map") / "data"
        storage = Storage.open(Settings(data_dir=data_dir))
        try:
            import_site(storage, site_dir, SITE, kinds=("mapping", "localisation"))
            with storage.blobs.batch() as batch, storage.db.session() as session:
                site = site_service.get_site(session, SITE)
                map_service.build_site_map(session, storage.blobs, batch, site, FAST)
        finally:
            storage.close()
        _BUILT[site_dir] = data_dir
    return _BUILT[site_dir]


def loc_drive_dir(site_dir: Path) -> Path:
    """The tiny site's first localisation drive folder."""
    return sorted(p for p in (site_dir / "drives").iterdir() if p.name.startswith("loc"))[0]
