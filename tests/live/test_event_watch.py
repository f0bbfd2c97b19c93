"""The event log kept by the live path on a real database: a frame's events, failures that leave the frame
alone, and stale events opened once however many processes look."""

from __future__ import annotations

import asyncio
from datetime import UTC, datetime, timedelta

import pytest
from sqlalchemy import func, select

from driftmap.live import event_watch
from driftmap.live.event_watch import SilenceWatch, open_stale_events, record_frame_events
from driftmap.services import events as event_service
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.services.events import EventChange
from driftmap.store.access_models import Vehicle, VehicleLiveState, VehiclePosition
from driftmap.store.event_models import VehicleEvent
from driftmap.store.storage import Storage

STALE_AFTER_S = 10.0
HEARD = datetime.now(UTC).replace(microsecond=0) - timedelta(hours=1)  # the vehicle's last position arrived


@pytest.fixture
def vehicle_id(storage: Storage) -> int:
    """A vehicle on a new site that reported once, at ``HEARD`` at (10, 20)."""
    with storage.db.session() as session:
        site = site_service.create_site(session, "north")
        vehicle, _token = vehicle_service.create_vehicle(session, "lhd-1", site.id)
        session.add(VehicleLiveState(vehicle_id=vehicle.id, reported_at=HEARD))
        session.add(
            VehiclePosition(
                vehicle_id=vehicle.id,
                t_s=5.0,
                node=0,
                x_m=10.0,
                y_m=20.0,
                confidence=0.99,
                matched=True,
                lost=False,
            )
        )
        session.flush()
        return vehicle.id


def _frame(storage: Storage, vehicle_id: int, active: set[str], at: datetime) -> list[tuple[str, str]]:
    with storage.db.session() as session:
        vehicle = session.get(Vehicle, vehicle_id)
        assert vehicle is not None
        changes = record_frame_events(session, vehicle, frozenset(active), at, 1.0, 2.0, {"obscured": "dust"})  # type: ignore[arg-type]
    return [(c.change, c.event.kind) for c in changes]


def _events(storage: Storage) -> list[VehicleEvent]:
    with storage.db.session() as session:
        return list(session.scalars(select(VehicleEvent).order_by(VehicleEvent.id)))


class TestFrameEvents:
    def test_frames_open_and_end_events_in_the_log(self, storage: Storage, vehicle_id: int) -> None:
        at = HEARD + timedelta(seconds=1)
        assert _frame(storage, vehicle_id, {"lost", "obscured"}, at) == [
            ("opened", "lost"),
            ("opened", "obscured"),
        ]
        assert _frame(storage, vehicle_id, {"obscured"}, at + timedelta(seconds=1)) == [("closed", "lost")]
        assert _frame(storage, vehicle_id, {"obscured"}, at + timedelta(seconds=2)) == []
        lost, obscured = _events(storage)
        assert (lost.kind, lost.x_m, lost.y_m, lost.detail) == ("lost", 1.0, 2.0, None)
        assert event_service.as_utc(lost.ended_at) == at + timedelta(seconds=1)  # type: ignore[arg-type]
        assert (obscured.kind, obscured.ended_at, obscured.detail) == ("obscured", None, "dust")

    def test_a_log_that_cannot_be_written_leaves_the_frame_alone(
        self,
        storage: Storage,
        vehicle_id: int,
        monkeypatch: pytest.MonkeyPatch,
        caplog: pytest.LogCaptureFixture,
    ) -> None:
        def broken(*_args: object, **_kwargs: object) -> EventChange:
            raise RuntimeError("disk on fire")

        _frame(storage, vehicle_id, {"obscured"}, HEARD)
        monkeypatch.setattr(event_service, "open_event", broken)
        with storage.db.session() as session:
            vehicle = session.get(Vehicle, vehicle_id)
            state = session.get(VehicleLiveState, vehicle_id)
            assert vehicle is not None and state is not None
            state.processed = 41  # the frame's own writes, before and after the log
            assert record_frame_events(session, vehicle, frozenset({"lost"}), HEARD, 0.0, 0.0) == ()
            state.skipped = 3
        with storage.db.session() as session:
            state = session.get(VehicleLiveState, vehicle_id)
            assert state is not None and (state.processed, state.skipped) == (41, 3)
        assert [(e.kind, e.ended_at) for e in _events(storage)] == [("obscured", None)]  # not ended either
        assert "could not update the event log" in caplog.text


class TestStale:
    def test_a_silent_vehicle_gets_one_stale_event_until_it_reports(
        self, storage: Storage, vehicle_id: int
    ) -> None:
        assert open_stale_events(storage.db, STALE_AFTER_S, HEARD + timedelta(seconds=9)) == []
        later = HEARD + timedelta(seconds=60)
        (opened,) = open_stale_events(storage.db, STALE_AFTER_S, later)
        event = opened.event
        assert (opened.change, event.kind, event.vehicle, event.x, event.y) == (
            "opened",
            "stale",
            "lhd-1",
            10.0,
            20.0,
        )
        assert event.started_at == HEARD + timedelta(seconds=STALE_AFTER_S) and event.ended_at is None
        assert open_stale_events(storage.db, STALE_AFTER_S, later) == []
        assert _frame(storage, vehicle_id, set(), later) == [("closed", "stale")]

    def test_two_processes_that_find_it_at_once_open_it_once(self, storage: Storage, vehicle_id: int) -> None:
        with storage.db.session() as session:
            (silent,) = event_service.silent_vehicles(session, HEARD + timedelta(seconds=1))
            first = event_service.open_event_once(session, silent.vehicle, "stale", HEARD, None, None)
            again = event_service.open_event_once(session, silent.vehicle, "stale", HEARD, None, None)
        assert first is not None and again is None
        with storage.db.session() as session:
            assert session.scalar(select(func.count()).select_from(VehicleEvent)) == 1

    def test_the_watch_publishes_what_it_opens(self, storage: Storage, vehicle_id: int) -> None:
        published: list[EventChange] = []

        async def publish(change: EventChange) -> None:
            published.append(change)

        watch = SilenceWatch(storage.db, publish, STALE_AFTER_S, every_s=0.01)
        assert asyncio.run(watch.check()) == published
        assert [(c.change, c.event.kind, c.event.vehicle_id) for c in published] == [
            ("opened", "stale", vehicle_id)
        ]

    def test_a_failing_look_is_logged_and_the_watch_goes_on(
        self,
        storage: Storage,
        vehicle_id: int,
        monkeypatch: pytest.MonkeyPatch,
        caplog: pytest.LogCaptureFixture,
    ) -> None:
        looks: list[int] = []

        def failing(*_args: object) -> list[EventChange]:
            looks.append(1)
            raise RuntimeError("database away")

        async def run() -> None:
            watch = SilenceWatch(storage.db, lambda _c: asyncio.sleep(0), STALE_AFTER_S, every_s=0.01)
            watch.start()
            while len(looks) < 3:
                await asyncio.sleep(0.01)
            await watch.stop()

        monkeypatch.setattr(event_watch, "open_stale_events", failing)
        asyncio.run(asyncio.wait_for(run(), 10.0))
        assert "could not look for silent vehicles" in caplog.text
