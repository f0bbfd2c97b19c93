"""Bad input on the live path (real app, real SQLite copy of the built tiny site, real localiser processes):
a refused frame never changes the vehicle's state, and image bombs are refused from their header."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import httpx
import numpy as np
import pytest

from driftmap.formats.frame_images import encode_png
from tests.api.access_helpers import (
    Actors,
    RecordedFrame,
    give_drive_camera,
    localisation_drive,
    recorded_frames,
)
from tests.image_bombs import zero_png

REFUSED_WITHIN_S = 10.0  # a guard against the defects fixed (a minute and gigabytes), not a speed figure


@pytest.fixture
def frames(tiny_site_dir: Path) -> list[RecordedFrame]:
    return recorded_frames(localisation_drive(tiny_site_dir), 3)


def _post(actors: Actors, data: bytes, t: float | str) -> httpx.Response:
    return actors.client.post(
        f"/api/vehicles/{actors.vehicle_id}/frames",
        params={"t": t},
        content=data,
        headers={**actors.auth("vehicle"), "Content-Type": "image/png"},
    )


def _status(response: httpx.Response) -> Any:
    assert response.status_code == 200, response.text
    return response.json()["status"]


class TestARefusedFrameChangesNothing:
    def test_a_bad_t_does_not_block_later_frames(
        self, live_actors: Actors, frames: list[RecordedFrame]
    ) -> None:
        assert _status(_post(live_actors, frames[0].data, 10.0)) == "processed"
        for bad in ("inf", "nan", "1e308"):
            refused = _post(live_actors, frames[1].data, bad)
            assert refused.status_code == 422 and refused.json()["errors"][0]["loc"] == ["query", "t"], bad
        assert _status(_post(live_actors, frames[1].data, 20.0)) == "processed"

    def test_a_frame_the_localiser_refuses_does_not_block_earlier_times(
        self, live_actors: Actors, frames: list[RecordedFrame], tiny_site_dir: Path
    ) -> None:
        block = give_drive_camera(live_actors, tiny_site_dir)
        assert _status(_post(live_actors, frames[0].data, 10.0)) == "processed"
        other_size = encode_png(np.full((block["height"] + 1, block["width"]), 128, dtype=np.uint8))
        refused = _post(live_actors, other_size, 30.0)
        assert refused.status_code == 422 and refused.json()["field"] == "body"
        assert "camera says" in refused.json()["detail"]
        assert _status(_post(live_actors, frames[1].data, 20.0)) == "processed"
        state = live_actors.client.get(
            f"/api/vehicles/{live_actors.vehicle_id}/live-state", headers=live_actors.auth("viewer")
        )
        assert state.status_code == 200, state.text  # the stored state knows nothing of the refused frame
        assert state.json()["last_t_s"] == 20.0 and state.json()["out_of_order"] == 0


class TestImageBombs:
    def test_a_live_frame_declaring_too_many_pixels_is_refused_at_once(self, live_actors: Actors) -> None:
        bomb = zero_png(30_000, 30_000)
        start = time.perf_counter()
        response = _post(live_actors, bomb, 1.0)
        assert time.perf_counter() - start < REFUSED_WITHIN_S
        assert response.status_code == 413, response.text
        assert response.json()["field"] == "body" and "30000x30000" in response.json()["detail"]
