"""One tiny simulated site per test session, imported into a real store on demand; a map version's poses."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from sqlalchemy import select

from driftmap.services import drives as drive_service
from driftmap.services import sites as site_service
from driftmap.sim import simulate_site
from driftmap.store.models import MapPose
from driftmap.store.storage import Storage

TINY_SEED = 3


def make_tiny_site(out: Path) -> Path:
    """Simulate the tiny site (no obscured copies) into ``out``; returns ``out``."""
    simulate_site(out, seed=TINY_SEED, size="tiny", obscurants=False)
    return out


def create_site(storage: Storage, site_dir: Path, name: str) -> None:
    """Create site ``name`` with ``site_dir``'s survey plan."""
    with storage.blobs.batch() as batch, storage.db.session() as session:
        site = site_service.create_site(session, name)
        site_service.add_survey_map(
            session, batch, site, (site_dir / "survey.dxf").read_bytes(), "survey.dxf"
        )


def import_folders(storage: Storage, name: str, folders: list[Path]) -> None:
    """Import the drive ``folders`` into site ``name``, one transaction each."""
    for folder in folders:
        with storage.blobs.batch() as batch, storage.db.session() as session:
            drive_service.import_drive(session, batch, site_service.get_site(session, name), folder)


def import_site(
    storage: Storage, site_dir: Path, name: str = "tiny", kinds: tuple[str, ...] = ("mapping",)
) -> None:
    """Create site ``name`` from ``site_dir``'s survey and import its drives of the given kinds."""
    create_site(storage, site_dir, name)
    import_drives(storage, site_dir, name, kinds)


def import_drives(storage: Storage, site_dir: Path, name: str, kinds: tuple[str, ...]) -> None:
    """Import ``site_dir``'s drives of the given kinds (``mapping``, ``localisation``) into site ``name``."""
    folders = drive_service.drive_folders_in(site_dir / "drives")
    import_folders(
        storage,
        name,
        [f for f in folders if ("mapping" if f.name.startswith("map") else "localisation") in kinds],
    )


def version_poses(storage: Storage, map_version_id: int) -> np.ndarray:
    """(F, 3) ``[x_m, y_m, yaw_rad]`` of a map version's frames, survey metres and radians, in frame order."""
    with storage.db.session() as session:
        rows = session.execute(
            select(MapPose.x_m, MapPose.y_m, MapPose.yaw_rad)
            .where(MapPose.map_version_id == map_version_id)
            .order_by(MapPose.frame_id)
        ).all()
    return np.array(rows, dtype=np.float64)
