"""Position history retention on the run's real database: every position kept while young, then one per
bucket per vehicle, then none; the same rows whichever pass runs; a bad policy named."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest
from sqlalchemy import select

from driftmap.errors import BadInputError
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.services.retention import RetentionPolicy, apply_retention
from driftmap.store.access_models import VehiclePosition
from driftmap.store.storage import Storage

NOW = datetime(2026, 12, 5, 12, 0, 0, tzinfo=UTC)
POLICY = RetentionPolicy(full_days=2.0, downsample_s=10.0, keep_days=30.0, catch_up_days=7.0)


def _history(storage: Storage) -> dict[str, int]:
    """Two vehicles, 2 positions a second for 60 s at each of several ages; returns vehicle name -> id."""
    ids = {}
    with storage.db.session() as session:
        site = site_service.create_site(session, "north")
        for name in ("loader", "truck"):
            vehicle, _token = vehicle_service.create_vehicle(session, name, site.id)
            ids[name] = vehicle.id
            for age_days in (0.5, 3.0, 5.0, 40.0):
                start = NOW - timedelta(days=age_days)
                for k in range(120):
                    received = start + timedelta(seconds=0.5 * k)
                    session.add(
                        VehiclePosition(
                            vehicle_id=vehicle.id,
                            t_s=received.timestamp(),
                            node=1,
                            x_m=float(k),
                            y_m=0.0,
                            confidence=0.9,
                            matched=True,
                            lost=False,
                            received_at=received,
                        )
                    )
    return ids


def _ages(storage: Storage, vehicle_id: int) -> dict[float, int]:
    with storage.db.session() as session:
        rows = session.scalars(
            select(VehiclePosition.received_at).where(VehiclePosition.vehicle_id == vehicle_id)
        ).all()
    out: dict[float, int] = {}
    for received in rows:
        stamp = received if received.tzinfo else received.replace(tzinfo=UTC)
        age = round((NOW - stamp).total_seconds() / 86400.0 * 2) / 2  # to the half day
        out[age] = out.get(age, 0) + 1
    return out


def test_young_kept_older_thinned_oldest_deleted(storage: Storage) -> None:
    ids = _history(storage)
    with storage.db.session() as session:
        done = apply_retention(session, POLICY, NOW)
    assert done.dropped == 2 * 120  # the 40-day-old minute of each vehicle
    assert done.thinned == 2 * 2 * (120 - 6)  # 3 and 5 days old: a minute keeps one position per 10 s
    for vehicle_id in ids.values():
        assert _ages(storage, vehicle_id) == {0.5: 120, 3.0: 6, 5.0: 6}


def test_passes_agree_and_repeat_nothing(storage: Storage) -> None:
    ids = _history(storage)
    with storage.db.session() as session:
        first = apply_retention(session, POLICY, NOW)
    with storage.db.session() as session:
        kept = set(session.scalars(select(VehiclePosition.id)).all())
        again = apply_retention(session, POLICY, NOW)
    assert first.thinned > 0 and (again.thinned, again.dropped) == (0, 0)
    with storage.db.session() as session:
        assert set(session.scalars(select(VehiclePosition.id)).all()) == kept
    assert _ages(storage, ids["truck"])[0.5] == 120


def test_zero_keeps_everything_for_ever(storage: Storage) -> None:
    ids = _history(storage)
    with storage.db.session() as session:
        done = apply_retention(session, RetentionPolicy(2.0, 0.0, 0.0, 7.0), NOW)
    assert (done.thinned, done.dropped) == (0, 0)
    assert sum(_ages(storage, ids["loader"]).values()) == 4 * 120


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [({"full_days": -1.0}, "history_full_days"), ({"keep_days": 1.0, "full_days": 7.0}, "history_keep_days")],
)
def test_a_bad_policy_is_named(kwargs: dict[str, float], field: str) -> None:
    with pytest.raises(BadInputError) as caught:
        RetentionPolicy(**kwargs)
    assert caught.value.field == field
