"""The event log's routes: list with filters and pages, CSV export, acknowledgement (recorded, idempotent,
pushed over ``/api/live`` to every watcher), the unacknowledged events in the live snapshot, and bad queries
named."""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import pytest

from driftmap.services import events as event_service
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.store.access_models import Vehicle
from tests.api.data_helpers import ApiUsers

T0 = datetime(2026, 12, 6, 8, 0, 0, tzinfo=UTC)


@dataclass(frozen=True)
class Log:
    """Two sites' vehicles with events: ids by name."""

    sites: dict[str, int]
    vehicles: dict[str, int]
    events: dict[str, int]


@pytest.fixture
def log(users: ApiUsers) -> Log:
    """lhd-1 (north): lost 08:00-08:01, obscured from 08:05 (acknowledged); truck (south): stale from 08:10."""
    with users.storage.db.session() as session:
        north, south = site_service.create_site(session, "north"), site_service.create_site(session, "south")
        lhd, _ = vehicle_service.create_vehicle(session, "lhd-1", north.id)
        truck, _ = vehicle_service.create_vehicle(session, "truck, 2", south.id)  # a comma for the CSV

        def at(minutes: float) -> datetime:
            return T0 + timedelta(minutes=minutes)

        lost = event_service.open_event(session, lhd, "lost", at(0), 10.5, -3.25).event.id
        event_service.end_events(session, lhd, ["lost"], at(1))
        obscured = event_service.open_event(session, lhd, "obscured", at(5), 11.0, -3.0, "dust").event.id
        event_service.acknowledge(session, obscured, 1, "admin", at(6))
        stale = event_service.open_event(session, truck, "stale", at(10), None, None).event.id
    return Log(
        {"north": north.id, "south": south.id},
        {"lhd-1": lhd.id, "truck": truck.id},
        {"lost": lost, "obscured": obscured, "stale": stale},
    )


def _ids(users: ApiUsers, **query: object) -> list[int]:
    page = users.get("/api/events", params=query)
    assert page["total"] == len(page["items"]) or "limit" in query
    return [e["id"] for e in page["items"]]


class TestList:
    def test_filters_combine_and_the_newest_comes_first(self, users: ApiUsers, log: Log) -> None:
        e = log.events
        assert _ids(users) == [e["stale"], e["obscured"], e["lost"]]
        assert _ids(users, site=log.sites["north"]) == [e["obscured"], e["lost"]]
        assert _ids(users, vehicle=log.vehicles["truck"]) == [e["stale"]]
        assert _ids(users, kind="lost") == [e["lost"]]
        assert _ids(users, open="true") == [e["stale"], e["obscured"]]
        assert _ids(users, open="false") == [e["lost"]]
        assert _ids(users, unacknowledged="true") == [e["stale"], e["lost"]]
        assert _ids(users, unacknowledged="false", open="true") == [e["obscured"]]
        # on at some moment of the range: the lost event ended at 08:01, the stale one started at 08:10
        assert _ids(users, since="2026-12-06T08:02:00Z") == [e["stale"], e["obscured"]]
        assert _ids(users, until="2026-12-06T08:09:00") == [e["obscured"], e["lost"]]  # no zone: UTC
        assert _ids(users, site=log.sites["south"], kind="lost") == []

    def test_pages(self, users: ApiUsers, log: Log) -> None:
        page = users.get("/api/events", params={"offset": 1, "limit": 1})
        assert (page["total"], page["offset"], page["limit"]) == (3, 1, 1)
        assert [e["id"] for e in page["items"]] == [log.events["obscured"]]

    def test_an_event_reads_with_its_vehicle_position_and_acknowledgement(
        self, users: ApiUsers, log: Log
    ) -> None:
        (obscured,) = users.get("/api/events", params={"kind": "obscured"})["items"]
        assert obscured == {
            "id": log.events["obscured"],
            "site_id": log.sites["north"],
            "vehicle_id": log.vehicles["lhd-1"],
            "vehicle": "lhd-1",
            "kind": "obscured",
            "detail": "dust",
            "started_at": "2026-12-06T08:05:00Z",
            "ended_at": None,
            "x": 11.0,
            "y": -3.0,
            "acknowledged_by": "admin",
            "acknowledged_at": "2026-12-06T08:06:00Z",
            "updated_at": "2026-12-06T08:06:00Z",
        }

    @pytest.mark.parametrize(
        ("query", "field"),
        [
            ({"kind": "fire"}, "kind"),
            ({"open": "maybe"}, "open"),
            ({"site": 0}, "site"),
            ({"since": "yesterday"}, "since"),
        ],
    )
    def test_bad_queries_are_422_naming_the_field(
        self, users: ApiUsers, query: dict[str, object], field: str
    ) -> None:
        for path in ("/api/events", "/api/events.csv"):
            response = users.client.get(path, params=query, headers=users.auth("viewer"))
            assert response.status_code == 422, response.text
            assert response.json()["errors"][0]["loc"] == ["query", field]

    def test_a_range_that_ends_before_it_starts_is_422_naming_until(self, users: ApiUsers) -> None:
        query = {"since": "2026-12-06T09:00:00Z", "until": "2026-12-06T08:00:00Z"}
        response = users.client.get("/api/events", params=query, headers=users.auth("viewer"))
        assert response.status_code == 422 and response.json()["field"] == "until"


class TestChangedSince:
    def test_a_watcher_that_fell_behind_gets_each_change_as_it_now_stands(
        self, users: ApiUsers, log: Log
    ) -> None:
        with users.storage.db.session() as session:
            changes = event_service.changed_since(session, T0 + timedelta(minutes=2), 10)
        assert [(c.change, c.event.id) for c in changes] == [
            ("acknowledged", log.events["obscured"]),  # opened at 08:05, acknowledged at 08:06
            ("opened", log.events["stale"]),
        ]


class TestCsv:
    def test_the_export_holds_the_filtered_events_oldest_first(self, users: ApiUsers, log: Log) -> None:
        response = users.client.get("/api/events.csv", params={"open": "true"}, headers=users.auth("viewer"))
        assert response.status_code == 200 and response.headers["content-type"].startswith("text/csv")
        assert 'filename="events.csv"' in response.headers["content-disposition"]
        rows = list(csv.DictReader(io.StringIO(response.text)))
        assert [r["kind"] for r in rows] == ["obscured", "stale"]
        obscured, stale = rows
        assert obscured["started_at"] == "2026-12-06T08:05:00.000Z" and obscured["ended_at"] == ""
        assert (obscured["x"], obscured["y"], obscured["detail"]) == ("11.0", "-3.0", "dust")
        assert (obscured["acknowledged_by"], obscured["acknowledged_at"]) == (
            "admin",
            "2026-12-06T08:06:00.000Z",
        )
        assert (stale["vehicle"], stale["x"], stale["acknowledged_by"]) == ("truck, 2", "", "")
        everything = users.client.get("/api/events.csv", headers=users.auth("viewer")).text
        lost = next(r for r in csv.DictReader(io.StringIO(everything)) if r["kind"] == "lost")
        assert lost["duration_s"] == "60.000" and lost["ended_at"] == "2026-12-06T08:01:00.000Z"


class TestAcknowledge:
    def test_an_acknowledgement_is_recorded_once_and_pushed_to_every_watcher(
        self, users: ApiUsers, log: Log
    ) -> None:
        stale = log.events["stale"]
        with users.client.websocket_connect("/api/live", headers=users.auth("admin")) as watcher:
            snapshot = watcher.receive_json()
            assert snapshot["type"] == "snapshot"
            assert [e["id"] for e in snapshot["events"]] == [stale, log.events["lost"]]  # unacknowledged
            before = datetime.now(UTC)
            response = users.client.post(f"/api/events/{stale}/ack", headers=users.auth("viewer"))
            assert response.status_code == 200, response.text
            acknowledged = response.json()
            assert acknowledged["acknowledged_by"] == "viewer" and acknowledged["ended_at"] is None
            assert datetime.fromisoformat(acknowledged["acknowledged_at"]) >= before - timedelta(seconds=1)
            pushed = watcher.receive_json()
            assert pushed == {"type": "event", "change": "acknowledged", **acknowledged}
        again = users.client.post(f"/api/events/{stale}/ack", headers=users.auth("surveyor"))
        assert again.status_code == 200 and again.json() == acknowledged  # the first acknowledgement stays
        assert _ids(users, unacknowledged="true") == [log.events["lost"]]

    def test_an_unknown_event_is_404(self, users: ApiUsers) -> None:
        response = users.client.post("/api/events/999/ack", headers=users.auth("viewer"))
        assert response.status_code == 404 and "999" in response.json()["detail"]

    def test_a_deleted_vehicle_takes_its_events_along(self, users: ApiUsers, log: Log) -> None:
        with users.storage.db.session() as session:
            vehicle = session.get(Vehicle, log.vehicles["lhd-1"])
            assert vehicle is not None
            vehicle_service.delete_vehicle(session, vehicle)
        assert _ids(users) == [log.events["stale"]]
