"""``GET /metrics`` after a vehicle posted frames: parsed with Prometheus's own parser, the live counters, the
localiser time, the request histogram by route template, vehicles by state and jobs by status."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from prometheus_client.parser import text_string_to_metric_families

from driftmap.config import Settings
from tests.api.access_helpers import Actors, RecordedFrame, localisation_drive, make_actors, recorded_frames


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
