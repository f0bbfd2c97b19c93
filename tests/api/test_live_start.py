"""A vehicle's known start given live (``POST /api/vehicles/{id}/start``), on the tiny site's stored map."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from driftmap.config import Settings
from driftmap.store.access_models import VehicleLiveState
from driftmap.store.storage import Storage
from tests.api.access_helpers import Actors, RecordedFrame, localisation_drive, make_actors, recorded_frames

NEAR_START_M = 10.0  # the first estimate after a start at the true position lies within this of it, metres
OFF_MAP_M = 500.0  # a start this far east of a frame's true position is off the tiny site's map, metres


@pytest.fixture
def frames(tiny_site_dir: Path) -> list[RecordedFrame]:
    return recorded_frames(localisation_drive(tiny_site_dir), 220)


@pytest.fixture
def actors(built: Path) -> Iterator[Actors]:
    made = make_actors(Settings(data_dir=built, stale_after_s=3600.0, live_processes=1), site_name="tiny")
    with made.client:
        yield made


def _start(actors: Actors, body: object, actor: str = "surveyor", vehicle_id: int | None = None) -> dict:  # type: ignore[type-arg]
    response = actors.client.post(
        f"/api/vehicles/{vehicle_id or actors.vehicle_id}/start", json=body, headers=actors.auth(actor)
    )
    answer: dict = {"status_code": response.status_code, **response.json()}  # type: ignore[type-arg]
    return answer


def _post(actors: Actors, frame: RecordedFrame) -> dict:  # type: ignore[type-arg]
    response = actors.client.post(
        f"/api/vehicles/{actors.vehicle_id}/frames",
        params={"t": frame.t},
        content=frame.data,
        headers={**actors.auth("vehicle"), "Content-Type": "image/png"},
    )
    assert response.status_code == 200, response.text
    body: dict = response.json()  # type: ignore[type-arg]
    return body


def _stored(actors: Actors) -> tuple[bytes | None, int, int, int | None]:
    """(state, revision, processed, map version id) of the vehicle's live state."""
    storage: Storage = actors.app.state.storage
    with storage.db.session() as session:
        state = session.get(VehicleLiveState, actors.vehicle_id)
        assert state is not None
        return state.state_npz, state.revision, state.processed, state.map_version_id


class TestKnownStart:
    def test_the_next_frame_is_localised_from_the_start(
        self, actors: Actors, frames: list[RecordedFrame]
    ) -> None:
        for frame in frames[:3]:
            _post(actors, frame)
        _state, revision, processed, _version = _stored(actors)
        there = frames[200]  # about 25 m from where the vehicle was last localised
        seeded = _start(actors, {"x": there.x, "y": there.y, "radius_m": 5.0})
        assert seeded["status_code"] == 200, seeded
        assert (seeded["vehicle_id"], seeded["x"], seeded["y"]) == (actors.vehicle_id, there.x, there.y)
        assert seeded["radius_m"] == 5.0 and seeded["map_version"] == 1 and seeded["node"] >= 0
        state, new_revision, new_processed, version = _stored(actors)
        assert state is not None and version is not None
        assert new_revision > revision and new_processed == processed
        answer = _post(actors, there)
        assert answer["status"] == "processed" and answer["processed"] == processed + 1
        assert np.hypot(answer["x"] - there.x, answer["y"] - there.y) <= NEAR_START_M
        # logged as an instant event, acknowledged by whoever set it
        events = actors.client.get(
            "/api/events", params={"kind": "start_known"}, headers=actors.auth("viewer")
        )
        (event,) = events.json()["items"]
        assert (event["vehicle_id"], event["x"], event["y"], event["detail"]) == (
            actors.vehicle_id,
            there.x,
            there.y,
            "radius 5 m",
        )
        assert event["ended_at"] == event["started_at"] and event["acknowledged_by"] == "surveyor"

    def test_the_radius_defaults_to_ten_metres_and_admins_may_seed(
        self, actors: Actors, frames: list[RecordedFrame]
    ) -> None:
        seeded = _start(actors, {"x": frames[0].x, "y": frames[0].y}, actor="admin")
        assert seeded["status_code"] == 200 and seeded["radius_m"] == 10.0
        answer = _post(actors, frames[0])
        assert np.hypot(answer["x"] - frames[0].x, answer["y"] - frames[0].y) <= NEAR_START_M

    def test_a_start_off_the_map_is_refused_naming_the_field_and_nothing_changes(
        self, actors: Actors, frames: list[RecordedFrame]
    ) -> None:
        _post(actors, frames[0])
        before = _stored(actors)
        east = _start(actors, {"x": frames[0].x + OFF_MAP_M, "y": frames[0].y})
        assert east["status_code"] == 422 and east["field"] == "x" and "from the map" in east["detail"]
        north = _start(actors, {"x": frames[0].x, "y": frames[0].y - OFF_MAP_M})
        assert north["status_code"] == 422 and north["field"] == "y"
        assert _stored(actors) == before

    @pytest.mark.parametrize(
        ("body", "field"),
        [
            ('{"x": NaN, "y": 0}', "x"),
            ('{"x": 0, "y": Infinity}', "y"),
            ('{"x": 0, "y": 0, "radius_m": -1}', "radius_m"),
            ('{"x": 0, "y": 0, "radius_m": 250}', "radius_m"),
        ],
    )
    def test_bad_values_are_named(self, actors: Actors, body: str, field: str) -> None:
        response = actors.client.post(
            f"/api/vehicles/{actors.vehicle_id}/start",
            content=body,
            headers={**actors.auth("surveyor"), "Content-Type": "application/json"},
        )
        assert response.status_code == 422, response.text
        assert (
            response.json()["field"] == field
        )  # NaN and Infinity refused with the JSON body, the rest by the service
        storage: Storage = actors.app.state.storage
        with storage.db.session() as session:
            assert session.get(VehicleLiveState, actors.vehicle_id) is None

    def test_malformed_bodies_are_422_naming_the_field(self, actors: Actors) -> None:
        text = _start(actors, {"x": "east", "y": 1.0})
        assert text["status_code"] == 422 and text["errors"][0]["loc"] == ["body", "x"]
        missing = _start(actors, {"x": 1.0})
        assert missing["status_code"] == 422 and missing["errors"][0]["loc"] == ["body", "y"]

    def test_viewers_and_vehicles_may_not_seed(self, actors: Actors, frames: list[RecordedFrame]) -> None:
        body = {"x": frames[0].x, "y": frames[0].y}
        assert _start(actors, body, actor="viewer")["status_code"] == 403
        assert _start(actors, body, actor="vehicle")["status_code"] == 403
        assert _start(actors, body, vehicle_id=424242)["status_code"] == 404


class TestWithoutAMap:
    def test_a_site_without_a_map_is_409(self, settings: Settings) -> None:
        actors = make_actors(settings)
        with actors.client:
            seeded = _start(actors, {"x": 0.0, "y": 0.0})
        assert seeded["status_code"] == 409 and "has no map" in seeded["detail"]
