"""Position queries on the run's real database: every vehicle's latest position, history in time order,
updates since a sequence number."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from driftmap.services import positions as position_service
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.store.access_models import VehiclePosition
from driftmap.store.storage import Storage

NOW = datetime(2026, 12, 5, 12, 0, 0, tzinfo=UTC)


def _fleet(storage: Storage) -> dict[str, int]:
    """Three vehicles on two sites; ``loader`` and ``truck`` report in turns (their rows interleave), ``idle``
    never reports. Returns name -> vehicle id."""
    with storage.db.session() as session:
        north = site_service.create_site(session, "north")
        south = site_service.create_site(session, "south")
        ids = {
            name: vehicle_service.create_vehicle(session, name, site.id)[0].id
            for name, site in (("loader", north), ("truck", south), ("idle", north))
        }
        for k in range(6):
            for name, clock0 in (("loader", 100.0), ("truck", 5000.0)):
                session.add(
                    VehiclePosition(
                        vehicle_id=ids[name], t_s=clock0 + k, node=k, x_m=float(k), y_m=-float(k),
                        confidence=0.5, matched=True, lost=False, received_at=NOW + timedelta(seconds=k),
                    )
                )  # fmt: skip
    return ids


def test_latest_is_each_vehicles_newest_position(storage: Storage) -> None:
    ids = _fleet(storage)
    with storage.db.session() as session:
        latest = position_service.latest(session, stale_after_s=1e9)
        assert [(v.vehicle, v.stale) for v in latest] == [("loader", False), ("truck", False), ("idle", True)]
        loader, truck, idle = latest
        assert loader.position is not None and (loader.position.t, loader.position.node) == (105.0, 5)
        assert truck.position is not None and truck.position.t == 5005.0
        assert truck.position.vehicle_id == ids["truck"] and idle.position is None
        assert loader.position.received_at == NOW + timedelta(seconds=5)
        north = position_service.latest(session, stale_after_s=1e9, site_id=loader.site_id)
        assert [v.vehicle for v in north] == ["loader", "idle"]


def test_history_and_since(storage: Storage) -> None:
    ids = _fleet(storage)
    with storage.db.session() as session:
        history = position_service.history(session, ids["truck"], 5001.0, 5003.5)
        assert [p.t for p in history] == [5001.0, 5002.0, 5003.0]
        site_id = history[0].site_id
        # every column lands in its field (an odometry flag never recorded reads False)
        assert history[0] == position_service.PositionView(
            seq=history[0].seq,
            vehicle_id=ids["truck"],
            vehicle="truck",
            site_id=site_id,
            t=5001.0,
            node=1,
            x=1.0,
            y=-1.0,
            yaw=None,
            confidence=0.5,
            matched=True,
            lost=False,
            map_version=None,
            received_at=NOW + timedelta(seconds=1),
        )
        since = position_service.since(session, history[0].seq)
        assert [p.seq for p in since] == sorted(p.seq for p in since)
        assert len(since) == 12 - 4  # rows 1-4: both vehicles at k = 0 and 1
