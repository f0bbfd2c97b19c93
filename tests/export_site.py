"""A store to export from: the built tiny site (map version 1, FAST) with two vehicles' position history.

The map is the session's built tiny map (:func:`tests.api.access_helpers.built_tiny_data`), copied once per
session (on PostgreSQL into a database of its own); the export tests only read it, so the service and CLI
tests share one copy. The API tests copy it again per module to add their users.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from driftmap.config import Settings
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.store.access_models import VehiclePosition
from driftmap.store.storage import Storage
from tests.api.access_helpers import built_tiny_data, copy_data_to_new_database

SITE = "tiny"
LOADER, TRUCK = "loader-1", "truck 2"


@dataclass(frozen=True)
class Track:
    """The positions stored for one vehicle: ``t`` seconds (vehicle clock), ``x, y`` metres, ``yaw`` radians."""

    vehicle: str
    t: list[float]
    x: list[float]
    y: list[float]
    yaw: list[float | None]


TRACKS = (
    Track(
        LOADER, [100.0 + k for k in range(10)], [5.0 + k for k in range(10)], [2.5] * 10, [0.0] * 9 + [None]
    ),
    Track(TRUCK, [50.0, 50.5, 51.0], [1.0, 2.0, 3.0], [-1.0, -1.5, -2.0], [1.5, 1.6, 1.7]),
)
_STORES: dict[Path, Settings] = {}


def add_positions(storage: Storage, site: str = SITE) -> None:
    """Create the vehicles of :data:`TRACKS` on ``site`` and store their positions (out of time order)."""
    with storage.db.session() as session:
        site_id = site_service.get_site(session, site).id
        for track in TRACKS:
            vehicle, _token = vehicle_service.create_vehicle(session, track.vehicle, site_id)
            for t, x, y, yaw in reversed(list(zip(track.t, track.x, track.y, track.yaw, strict=True))):
                session.add(
                    VehiclePosition(
                        vehicle_id=vehicle.id,
                        t_s=t,
                        node=1,
                        x_m=x,
                        y_m=y,
                        yaw_rad=yaw,
                        confidence=0.75,
                        matched=True,
                        lost=False,
                        speed_mps=None,
                    )
                )


def export_store(tmp_path_factory: pytest.TempPathFactory, site_dir: Path) -> Settings:
    """Settings of the session's store to export from (built once, then only read)."""
    if site_dir not in _STORES:
        data, database_url = copy_data_to_new_database(
            built_tiny_data(tmp_path_factory.getbasetemp(), site_dir),
            tmp_path_factory.mktemp("export-site") / "data",
        )
        settings = Settings(data_dir=data, database_url=database_url)
        storage = Storage.open(settings)
        try:
            add_positions(storage)
        finally:
            storage.close()
        _STORES[site_dir] = settings
    return _STORES[site_dir]
