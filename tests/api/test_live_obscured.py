"""The obscured-camera judgement through the live API: in the frame answer, the stored history, the latest
positions and ``/api/live``, and carried over to another server process with the vehicle's stored state; and
the vehicle's latest frame (the picture the control room checks when the camera looks obscured)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient

from driftmap.api.app import create_app
from driftmap.config import Settings
from driftmap.core.localisation.camera_check import OBSCURED_DEFAULT
from driftmap.formats.frame_images import decode_gray, encode_png
from driftmap.sim.obscurants import LEVELS, apply_level
from tests.api.access_helpers import (
    Actors,
    RecordedFrame,
    localisation_drive,
    make_actors,
    recorded_frames,
)

CLEAN = 15  # clean frames first (more than the warm-up), then dusty ones
DUSTY = 15


@pytest.fixture
def frames(tiny_site_dir: Path) -> list[RecordedFrame]:
    """Clean frames, then the next frames with dust level 2 on the lens."""
    recorded = recorded_frames(localisation_drive(tiny_site_dir), CLEAN + DUSTY)
    rng = np.random.default_rng(5)
    dusty = [
        RecordedFrame(f.t, f.x, f.y, encode_png(apply_level(decode_gray(f.data), LEVELS["dust2"], rng)))
        for f in recorded[CLEAN:]
    ]
    return recorded[:CLEAN] + dusty


@pytest.fixture
def actors(built: Path) -> Iterator[Actors]:
    made = make_actors(Settings(data_dir=built, stale_after_s=3600.0, live_processes=1), site_name="tiny")
    with made.client:
        yield made


def _post(client: TestClient, actors: Actors, frame: RecordedFrame) -> dict:  # type: ignore[type-arg]
    response = client.post(
        f"/api/vehicles/{actors.vehicle_id}/frames",
        params={"t": frame.t},
        content=frame.data,
        headers={**actors.auth("vehicle"), "Content-Type": "image/png"},
    )
    assert response.status_code == 200, response.text
    body: dict = response.json()  # type: ignore[type-arg]
    return body


class TestObscuredLive:
    def test_dust_turns_the_vehicle_obscured_everywhere(
        self, actors: Actors, frames: list[RecordedFrame]
    ) -> None:
        answers = [_post(actors.client, actors, f) for f in frames]
        assert [a["obscured"] for a in answers[:CLEAN]] == [False] * CLEAN
        assert answers[CLEAN - 1]["speckle"] < OBSCURED_DEFAULT.speckle_max / 10
        assert all(0.8 < a["salient"] <= 1.0 and a["sharpness"] > 0 for a in answers[:CLEAN])
        assert answers[-1]["obscured"] is True and answers[-1]["obscured_reason"] == "dust"
        first = next(i for i, a in enumerate(answers) if a["obscured"])
        assert CLEAN <= first <= CLEAN + 3  # the smoothed speckle passes its threshold within a few frames

        viewer = actors.auth("viewer")
        history = actors.client.get(f"/api/vehicles/{actors.vehicle_id}/positions", headers=viewer).json()
        assert [h["obscured"] for h in history] == [a["obscured"] for a in answers]
        assert history[-1]["obscured_reason"] == "dust" and history[-1]["speckle"] == answers[-1]["speckle"]
        latest = actors.client.get("/api/positions/latest", headers=viewer).json()
        mine = next(v for v in latest if v["vehicle_id"] == actors.vehicle_id)
        assert mine["position"]["obscured"] is True
        # the event log: the camera obscured since the first obscured frame, where the vehicle was then
        query = {"vehicle": actors.vehicle_id, "kind": "obscured"}
        (event,) = actors.client.get("/api/events", params=query, headers=viewer).json()["items"]
        assert (event["ended_at"], event["detail"]) == (None, "dust")
        assert (event["x"], event["y"]) == (answers[first]["x"], answers[first]["y"])
        latest_frame = actors.client.get(f"/api/vehicles/{actors.vehicle_id}/frames/latest", headers=viewer)
        assert latest_frame.status_code == 200 and latest_frame.content == frames[-1].data
        assert latest_frame.headers["content-type"] == "image/png"
        assert float(latest_frame.headers["x-frame-t"]) == frames[-1].t
        none_yet = actors.client.get(f"/api/vehicles/{actors.other_vehicle_id}/frames/latest", headers=viewer)
        assert none_yet.status_code == 404
        with actors.client.websocket_connect("/api/live", headers=viewer) as ws:
            snapshot = ws.receive_json()
        row = next(v for v in snapshot["vehicles"] if v["vehicle_id"] == actors.vehicle_id)
        assert row["position"]["obscured"] is True and row["position"]["obscured_reason"] == "dust"

    def test_the_judgement_carries_over_to_another_server(
        self, built: Path, frames: list[RecordedFrame]
    ) -> None:
        first = make_actors(Settings(data_dir=built, live_processes=1), site_name="tiny")
        with first.client:
            for f in frames[:-1]:
                _post(first.client, first, f)
        with TestClient(create_app(Settings(data_dir=built, live_processes=1))) as client:
            answer = _post(client, first, frames[-1])
        # a fresh judgement would still be warming up (one frame); the stored memory says dust at once
        assert answer["obscured"] is True and answer["obscured_reason"] == "dust"
