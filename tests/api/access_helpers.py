"""What the access and live API tests share: users of every role, a vehicle, a built tiny site.

The tiny site's map is built once per test session into a data directory (and, on a PostgreSQL run, a
database) that each test copies, so tests that post frames start from the same stored map and never see each
other's vehicles.
"""

from __future__ import annotations

import csv
import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from fastapi import FastAPI
from fastapi.testclient import TestClient

from driftmap.api.app import create_app
from driftmap.config import Settings
from driftmap.core.mapping.pipeline import MAPPING_FAST
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.services import users as user_service
from driftmap.services import vehicles as vehicle_service
from driftmap.store.storage import Storage
from tests.postgres_server import active_server
from tests.sim_site import import_site

PASSWORD = "correct horse battery"
ROLES = ("admin", "surveyor", "viewer")
_built: dict[Path, Path] = {}
_snapshots: dict[Path, str] = {}
"""PostgreSQL database holding the rows of a built data directory (PostgreSQL runs only)."""


def built_tiny_data(base: Path, site_dir: Path) -> Path:
    """A data directory holding the tiny site and one FAST map version (built once per session)."""
    if site_dir not in _built:
        data = base / "built-tiny-data"
        server = active_server()
        url = None  # the embedded SQLite file, whatever the test's database is
        if server is not None:
            _snapshots[data], url = server.snapshot()
        storage = Storage.open(Settings(data_dir=data, database_url=url))
        import_site(storage, site_dir)
        with storage.blobs.batch() as batch, storage.db.session() as session:
            map_service.build_site_map(
                session, storage.blobs, batch, site_service.get_site(session, "tiny"), MAPPING_FAST
            )
        storage.close()
        _built[site_dir] = data
    return _built[site_dir]


def copy_data(source: Path, target: Path) -> Path:
    """A private copy of a data directory (SQLite file, WAL and blobs; on PostgreSQL, its rows too)."""
    shutil.copytree(source, target)
    server = active_server()
    if server is not None and source in _snapshots:
        server.restore_current(_snapshots[source])
    return target


def copy_data_to_new_database(source: Path, target: Path) -> tuple[Path, str | None]:
    """A private copy of a data directory for a fixture that outlives one test (e.g. module-scoped):
    on PostgreSQL its rows go to a new database of their own, whose URL is returned (None on SQLite)."""
    shutil.copytree(source, target)
    server = active_server()
    if server is None or source not in _snapshots:
        return target, None
    _name, url = server.snapshot(template=_snapshots[source])
    return target, url


@dataclass
class Actors:
    """A running app with a user of every role and one vehicle of site 1, and their tokens."""

    app: FastAPI
    client: TestClient
    tokens: dict[str, str]
    """Bearer token by actor: ``admin``, ``surveyor``, ``viewer``, ``vehicle``, ``other_vehicle``."""
    vehicle_id: int
    other_vehicle_id: int

    def auth(self, actor: str | None) -> dict[str, str]:
        """The Authorization header of an actor (none for None)."""
        return {} if actor is None else {"Authorization": f"Bearer {self.tokens[actor]}"}


def make_actors(settings: Settings, *, site_name: str | None = None) -> Actors:
    """Open an app on ``settings`` with users of every role and two vehicles (site ``site_name`` or a new one)."""
    app = create_app(settings)
    storage: Storage = app.state.storage
    with storage.db.session() as session:
        site = (
            site_service.get_site(session, site_name)
            if site_name
            else site_service.create_site(session, "access-test")
        )
        for role in ROLES:
            user_service.create_user(session, role, PASSWORD, role)
        vehicle, token = vehicle_service.create_vehicle(session, "lhd-1", site.id)
        other, other_token = vehicle_service.create_vehicle(session, "lhd-2", site.id)
        ids = vehicle.id, other.id
    client = TestClient(app)
    tokens = {"vehicle": token, "other_vehicle": other_token}
    for role in ROLES:
        response = client.post("/api/auth/login", json={"username": role, "password": PASSWORD})
        assert response.status_code == 200, response.text
        tokens[role] = response.json()["access_token"]
    client.cookies.clear()  # each request states its actor explicitly
    return Actors(app, client, tokens, *ids)


@dataclass(frozen=True)
class RecordedFrame:
    """One frame of a simulated drive: its time, true position and encoded bytes."""

    t: float
    x: float
    y: float
    data: bytes


def recorded_frames(drive_dir: Path, count: int | None = None) -> list[RecordedFrame]:
    """The first ``count`` frames of a drive folder (all when None)."""
    with (drive_dir / "frames.csv").open() as handle:
        rows = list(csv.DictReader(handle))[:count]
    return [
        RecordedFrame(
            float(r["t"]),
            float(r["x"]),
            float(r["y"]),
            (drive_dir / "frames" / f"{int(r['frame']):06d}.png").read_bytes(),
        )
        for r in rows
    ]


def localisation_drive(site_dir: Path) -> Path:
    """The tiny site's first localisation drive folder."""
    return sorted(p for p in (site_dir / "drives").iterdir() if p.name.startswith("loc"))[0]


def give_drive_camera(actors: Actors, site_dir: Path) -> dict[str, Any]:
    """Set the camera of the site's localisation drive as ``actors``' vehicle's camera; returns the block."""
    block: dict[str, Any] = json.loads((localisation_drive(site_dir) / "drive.json").read_text())["camera"]
    response = actors.client.put(
        f"/api/vehicles/{actors.vehicle_id}/camera", json=block, headers=actors.auth("surveyor")
    )
    assert response.status_code == 200, response.text
    return block
