"""``GET /metrics`` after a vehicle posted frames: parsed with Prometheus's own parser, the live counters, the
localiser time, the request histogram by route template, vehicles by state and jobs by status."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import pytest
from prometheus_client.parser import text_string_to_metric_families

from driftmap.config import Settings
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.store.access_models import VehiclePosition
from driftmap.store.models import utc_now
from driftmap.store.storage import Storage
from tests.api.access_helpers import Actors, RecordedFrame, localisation_drive, make_actors, recorded_frames

VEHICLE_STATES = ("reporting", "lost", "obscured", "stale", "never")
STATES = {  # vehicle -> (lost, obscured, age of its latest position in s) beside lhd-1 and lhd-2
    "dark": (True, False, 5.0),
    "dusty": (False, True, 5.0),
    "parked": (False, False, 7200.0),
    "gone": (True, True, 7200.0),
}


@pytest.fixture
def actors(built: Path) -> Iterator[Actors]:
    made = make_actors(Settings(data_dir=built, stale_after_s=3600.0, live_processes=1), site_name="tiny")
    with made.client:
        yield made


def _scrape(actors: Actors) -> dict[str, list]:  # type: ignore[type-arg]
    response = actors.client.get("/metrics")  # no credentials: open as /api/health is
    assert response.status_code == 200, response.text
    assert response.headers["content-type"].startswith("text/plain")
    samples: dict[str, list] = {}  # type: ignore[type-arg]
    for family in text_string_to_metric_families(response.text):
        for sample in family.samples:
            samples.setdefault(sample.name, []).append(sample)
    return samples


def _value(samples: dict[str, list], name: str, **labels: str) -> float:  # type: ignore[type-arg]
    return sum(s.value for s in samples.get(name, []) if all(s.labels.get(k) == v for k, v in labels.items()))


def test_live_frames_requests_and_states_are_counted(actors: Actors, tiny_site_dir: Path) -> None:
    before = _scrape(actors)
    frames: list[RecordedFrame] = recorded_frames(localisation_drive(tiny_site_dir), 12)
    for f in frames:
        r = actors.client.post(
            f"/api/vehicles/{actors.vehicle_id}/frames",
            params={"t": f.t},
            content=f.data,
            headers={**actors.auth("vehicle"), "Content-Type": "image/png"},
        )
        assert r.status_code == 200 and r.json()["status"] == "processed", r.text
    late = actors.client.post(
        f"/api/vehicles/{actors.vehicle_id}/frames",
        params={"t": frames[0].t},
        content=frames[0].data,
        headers={**actors.auth("vehicle"), "Content-Type": "image/png"},
    )
    assert late.json()["status"] == "out_of_order"
    after = _scrape(actors)

    def grew(name: str, **labels: str) -> float:
        return _value(after, name, **labels) - _value(before, name, **labels)

    assert grew("driftmap_live_frames_total", status="processed") == len(frames)
    assert grew("driftmap_live_frames_total", status="out_of_order") == 1
    assert grew("driftmap_localise_seconds_count") == len(frames)
    assert 0 < grew("driftmap_localise_seconds_sum") < 60
    route = "/api/vehicles/{vehicle_id}/frames"  # the template, not the vehicle's id
    assert grew("driftmap_http_request_duration_seconds_count", route=route, status="200") == len(frames) + 1
    assert not any(str(actors.vehicle_id) in s.labels.get("route", "") for s in after.get(
        "driftmap_http_request_duration_seconds_count", []))  # fmt: skip
    assert _value(after, "driftmap_vehicles", state="reporting") == 1  # the vehicle that posted
    assert _value(after, "driftmap_vehicles", state="never") == 1  # the other one
    assert _value(after, "driftmap_jobs", status="queued") == 0


def test_a_bad_request_is_timed_under_its_route(actors: Actors) -> None:
    actors.client.get("/api/sites/999999", headers=actors.auth("viewer"))
    samples = _scrape(actors)
    assert (
        _value(
            samples,
            "driftmap_http_request_duration_seconds_count",
            route="/api/sites/{site_id}",
            status="404",
        )
        == 1
    )


def _position(vehicle_id: int, *, lost: bool, obscured: bool, age_s: float) -> VehiclePosition:
    return VehiclePosition(
        vehicle_id=vehicle_id, t_s=0.0, node=1, x_m=0.0, y_m=0.0, confidence=0.9, matched=not lost,
        lost=lost, obscured=obscured, received_at=utc_now() - timedelta(seconds=age_s),
    )  # fmt: skip


def test_vehicle_states_and_the_queue_depth_are_counted_at_each_scrape(actors: Actors) -> None:
    """Each vehicle is counted under the state of its latest position (stale before lost or obscured), and
    jobs accepted while no worker runs are the queue depth."""
    storage: Storage = actors.app.state.storage
    with storage.db.session() as session:
        site_id = site_service.get_site(session, "tiny").id
        made = {name: vehicle_service.create_vehicle(session, name, site_id)[0].id for name in STATES}
        vehicle_service.create_vehicle(session, "idle", site_id)  # no position yet
        session.add(_position(actors.vehicle_id, lost=False, obscured=False, age_s=1.0))
        session.add(_position(actors.other_vehicle_id, lost=True, obscured=False, age_s=7200.0))  # older
        session.add(_position(actors.other_vehicle_id, lost=True, obscured=False, age_s=1.0))  # latest
        for name, (lost, obscured, age_s) in STATES.items():
            session.add(_position(made[name], lost=lost, obscured=obscured, age_s=age_s))
    before = _scrape(actors)
    assert {s: _value(before, "driftmap_vehicles", state=s) for s in VEHICLE_STATES} == {
        "reporting": 1,
        "lost": 2,  # the other vehicle by its latest position, and "dark"
        "obscured": 1,
        "stale": 2,  # an hour past stale_after_s outweighs lost or obscured
        "never": 1,
    }
    queued = _value(before, "driftmap_jobs", status="queued")
    accepted = [
        actors.client.post(
            f"/api/sites/{site_id}/maps", json={"preset": "fast"}, headers=actors.auth("surveyor")
        ),
        actors.client.post("/api/sites/simulate", json={"name": "far", "size": "tiny"},
                           headers=actors.auth("admin")),
    ]  # fmt: skip
    assert [r.status_code for r in accepted] == [202, 202], [r.text for r in accepted]
    assert all(r.json()["status"] == "queued" for r in accepted)
    after = _scrape(actors)
    assert _value(after, "driftmap_jobs", status="queued") == queued + 2  # no worker runs here
    assert _value(after, "driftmap_jobs", status="running") == 0
