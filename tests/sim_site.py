"""One tiny simulated site per test session, imported into a real SQLite store on demand."""

from __future__ import annotations

from pathlib import Path

from driftmap.services import drives as drive_service
from driftmap.services import sites as site_service
from driftmap.sim import simulate_site
from driftmap.store.storage import Storage

TINY_SEED = 3


def make_tiny_site(out: Path) -> Path:
    """Simulate the tiny site (no obscured copies) into ``out``; returns ``out``."""
    simulate_site(out, seed=TINY_SEED, size="tiny", obscurants=False)
    return out


def import_site(
    storage: Storage, site_dir: Path, name: str = "tiny", kinds: tuple[str, ...] = ("mapping",)
) -> None:
    """Create site ``name`` from ``site_dir``'s survey and import its drives of the given kinds."""
    with storage.blobs.batch() as batch, storage.db.session() as session:
        site = site_service.create_site(session, name)
        site_service.add_survey_map(
            session, batch, site, (site_dir / "survey.dxf").read_bytes(), "survey.dxf"
        )
    import_drives(storage, site_dir, name, kinds)


def import_drives(storage: Storage, site_dir: Path, name: str, kinds: tuple[str, ...]) -> None:
    """Import ``site_dir``'s drives of the given kinds (``mapping``, ``localisation``) into site ``name``."""
    for folder in drive_service.drive_folders_in(site_dir / "drives"):
        kind = "mapping" if folder.name.startswith("map") else "localisation"
        if kind not in kinds:
            continue
        with storage.blobs.batch() as batch, storage.db.session() as session:
            drive_service.import_drive(session, batch, site_service.get_site(session, name), folder)
