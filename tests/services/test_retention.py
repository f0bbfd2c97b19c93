"""Position history retention on the run's real database: every position kept while young, then one per
bucket per vehicle, then none; the same rows whichever pass runs; of the event log only the ended,
acknowledged events past the same age deleted; a bad policy named."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest
from sqlalchemy import select

from driftmap.errors import BadInputError
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.services.retention import RetentionPolicy, apply_retention
from driftmap.store.access_models import VehiclePosition
from driftmap.store.event_models import VehicleEvent
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


def _events(storage: Storage) -> dict[str, int]:
    """One vehicle's events of several ages and states; returns a label -> event id."""
    old, young = NOW - timedelta(days=40), NOW - timedelta(days=3)
    shapes = {  # label: (started, ended, acknowledged)
        "old, ended, acknowledged": (old, old + timedelta(minutes=5), old + timedelta(minutes=1)),
        "old, ended, never acknowledged": (old, old + timedelta(minutes=5), None),
        "old, still open, acknowledged": (old, None, old + timedelta(minutes=1)),
        "old, ended, acknowledged lately": (old, old + timedelta(minutes=5), young),
        "young, ended, acknowledged": (young, young + timedelta(minutes=5), young),
    }
    ids = {}
    with storage.db.session() as session:
        site = site_service.create_site(session, "east")
        vehicle, _token = vehicle_service.create_vehicle(session, "dozer", site.id)
        for label, (started, ended, acknowledged) in shapes.items():
            kind = "obscured" if ended is None else "lost"  # one open event of a kind per vehicle
            row = VehicleEvent(
                site_id=site.id,
                vehicle_id=vehicle.id,
                kind=kind,
                started_at=started,
                ended_at=ended,
                acknowledged_by=None if acknowledged is None else "admin",
                acknowledged_at=acknowledged,
            )
            row.updated_at = max(t for t in (started, ended, acknowledged) if t is not None)
            session.add(row)
            session.flush()
            ids[label] = row.id
    return ids


def _event_ids(storage: Storage) -> set[int]:
    with storage.db.session() as session:
        return set(session.scalars(select(VehicleEvent.id)).all())


def test_ended_acknowledged_events_past_keep_days_go_the_rest_stay(storage: Storage) -> None:
    ids = _events(storage)
    with storage.db.session() as session:
        done = apply_retention(session, POLICY, NOW)
    assert done.events_dropped == 1
    assert _event_ids(storage) == set(ids.values()) - {ids["old, ended, acknowledged"]}
    with storage.db.session() as session:
        assert apply_retention(session, POLICY, NOW).events_dropped == 0


def test_zero_keep_days_keeps_every_event(storage: Storage) -> None:
    ids = _events(storage)
    with storage.db.session() as session:
        done = apply_retention(session, RetentionPolicy(2.0, 10.0, 0.0, 7.0), NOW)
    assert done.events_dropped == 0
    assert _event_ids(storage) == set(ids.values())
