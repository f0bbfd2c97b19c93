"""Live localisation through the API on the tiny simulated site's stored map (real SQLite, real localiser).

Frames of the site's localisation drive are posted as a vehicle would; estimates are compared with the
simulator's ground truth. Overload is produced by submitting a burst of frames at once to the lanes.
"""

from __future__ import annotations

import asyncio
import math
import os
import signal
import struct
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from fastapi.testclient import TestClient
from starlette.websockets import WebSocketDisconnect

from driftmap.api import live as live_api
from driftmap.api.app import create_app
from driftmap.api.schemas_live import event_message, position_message
from driftmap.config import Settings
from driftmap.errors import ConflictError
from driftmap.formats.frame_images import decode_gray, encode_png
from driftmap.live.hub import InMemoryHub
from driftmap.live.ingest import LiveService
from driftmap.live.metrics import LIVE_REGISTRY
from driftmap.services import localisation as loc_service
from driftmap.services import sites as site_service
from driftmap.services import vehicles as vehicle_service
from driftmap.store.access_models import VehicleLiveState
from driftmap.store.storage import Storage
from tests.api.access_helpers import (
    Actors,
    RecordedFrame,
    give_drive_camera,
    localisation_drive,
    make_actors,
    recorded_frames,
)

ON_NODE_M = 15.0  # an estimate is right when it lies within this of the true position, metres
MIN_RIGHT = 0.8  # fraction of matched estimates that must be right
MIN_MATCHED = 0.1  # fraction of frames of the drive's first 15 s that must be matched (the calibrated
# confidence of a track that starts globally stays below the threshold for its first seconds)
DRIVE_FRAMES = 150


@pytest.fixture
def frames(tiny_site_dir: Path) -> list[RecordedFrame]:
    return recorded_frames(localisation_drive(tiny_site_dir), DRIVE_FRAMES)


@pytest.fixture
def actors(built: Path) -> Iterator[Actors]:
    made = make_actors(Settings(data_dir=built, stale_after_s=3600.0, live_processes=1), site_name="tiny")
    with made.client:
        yield made


def post(actors: Actors, frame: RecordedFrame, t: float | None = None, vehicle: str = "vehicle") -> dict:  # type: ignore[type-arg]
    response = actors.client.post(
        f"/api/vehicles/{actors.vehicle_id}/frames",
        params={"t": frame.t if t is None else t},
        content=frame.data,
        headers={**actors.auth(vehicle), "Content-Type": "image/png"},
    )
    assert response.status_code == 200, response.text
    body: dict = response.json()  # type: ignore[type-arg]
    return body


class TestFrames:
    def test_a_drive_posted_in_order_lands_near_the_truth(
        self, actors: Actors, frames: list[RecordedFrame]
    ) -> None:
        answers = [post(actors, f) for f in frames]
        assert [a["status"] for a in answers] == ["processed"] * len(frames)
        error = np.array([np.hypot(a["x"] - f.x, a["y"] - f.y) for a, f in zip(answers, frames, strict=True)])
        matched = np.array([a["matched"] for a in answers])
        assert matched.mean() >= MIN_MATCHED
        assert (error[matched] <= ON_NODE_M).mean() >= MIN_RIGHT
        assert np.median(error) <= ON_NODE_M
        assert answers[-1]["processed"] == len(frames) and answers[-1]["skipped"] == 0
        history = actors.client.get(
            f"/api/vehicles/{actors.vehicle_id}/positions", headers=actors.auth("viewer")
        ).json()
        assert [p["t"] for p in history] == [f.t for f in frames]
        assert [p["seq"] for p in history] == [a["seq"] for a in answers]
        window = actors.client.get(
            f"/api/vehicles/{actors.vehicle_id}/positions",
            params={"start": frames[10].t, "end": frames[19].t},
            headers=actors.auth("viewer"),
        ).json()
        assert len(window) == 10

    def test_state_carries_over_to_another_server_on_the_same_database(
        self, built: Path, frames: list[RecordedFrame]
    ) -> None:
        first = make_actors(Settings(data_dir=built, live_processes=1), site_name="tiny")
        with first.client:
            nodes = [post(first, f)["node"] for f in frames[:30]]
        with TestClient(create_app(Settings(data_dir=built, live_processes=1))) as client:
            for f in frames[30:60]:
                response = client.post(
                    f"/api/vehicles/{first.vehicle_id}/frames",
                    params={"t": f.t},
                    content=f.data,
                    headers={**first.auth("vehicle"), "Content-Type": "image/png"},
                )
                nodes.append(response.json()["node"])
            again = client.post(
                f"/api/vehicles/{first.vehicle_id}/frames",
                params={"t": frames[59].t},
                content=frames[59].data,
                headers={**first.auth("vehicle"), "Content-Type": "image/png"},
            )
            assert again.json()["status"] == "out_of_order"
        storage = Storage.open(Settings(data_dir=built))
        with storage.db.session() as session:
            lmap = loc_service.load_localiser_map(
                session, storage.blobs, site_service.get_site(session, "tiny")
            )
        storage.close()
        localiser = loc_service.make_localiser(lmap)
        continuous = [localiser.step(decode_gray(f.data), f.t).node for f in frames[:60]]
        assert nodes == continuous

    def test_out_of_order_frames_are_refused_and_counted(
        self, actors: Actors, frames: list[RecordedFrame]
    ) -> None:
        assert post(actors, frames[0], t=5.0)["status"] == "processed"
        assert post(actors, frames[1], t=4.0)["status"] == "out_of_order"
        refused = post(actors, frames[1], t=5.0)
        assert refused["status"] == "out_of_order" and refused["x"] is None and refused["out_of_order"] == 2
        assert post(actors, frames[1], t=6.0)["status"] == "processed"
        viewer = actors.auth("viewer")
        history = actors.client.get(f"/api/vehicles/{actors.vehicle_id}/positions", headers=viewer).json()
        assert [p["t"] for p in history] == [5.0, 6.0]
        state = actors.client.get(f"/api/vehicles/{actors.vehicle_id}/live-state", headers=viewer).json()
        assert (state["processed"], state["out_of_order"], state["last_t_s"]) == (2, 2, 6.0)

    def test_bad_frames_are_named_and_the_server_keeps_serving(
        self, actors: Actors, frames: list[RecordedFrame]
    ) -> None:
        url = f"/api/vehicles/{actors.vehicle_id}/frames"
        vehicle = actors.auth("vehicle")
        garbage = actors.client.post(
            url, params={"t": 1}, content=b"not an image", headers={**vehicle, "Content-Type": "image/png"}
        )
        assert garbage.status_code == 422 and "not a PNG or JPEG" in garbage.json()["detail"]
        cut = actors.client.post(
            url,
            params={"t": 1},
            content=frames[0].data[: len(frames[0].data) // 2],
            headers={**vehicle, "Content-Type": "image/png"},
        )
        assert cut.status_code == 422
        wrong_type = actors.client.post(
            url, params={"t": 1}, content=frames[0].data, headers={**vehicle, "Content-Type": "text/plain"}
        )
        assert wrong_type.status_code == 400 and wrong_type.json()["field"] == "content-type"
        no_t = actors.client.post(
            url, content=frames[0].data, headers={**vehicle, "Content-Type": "image/png"}
        )
        assert no_t.status_code == 422
        tiny = encode_png(np.full((6, 5), 128, dtype=np.uint8))
        odd = actors.client.post(
            url, params={"t": 1}, content=tiny, headers={**vehicle, "Content-Type": "image/png"}
        )
        assert odd.status_code in (200, 422)
        assert post(actors, frames[0], t=2.0)["status"] == "processed"

    def test_oversized_frame_is_413(self, built: Path, frames: list[RecordedFrame]) -> None:
        actors = make_actors(Settings(data_dir=built, max_frame_bytes=1000), site_name="tiny")
        response = actors.client.post(
            f"/api/vehicles/{actors.vehicle_id}/frames",
            params={"t": 1},
            content=frames[0].data,
            headers={**actors.auth("vehicle"), "Content-Type": "image/png"},
        )
        assert response.status_code == 413 and "1000 byte limit" in response.json()["detail"]

    def test_a_site_without_a_map_is_409(self, settings: Settings, frames: list[RecordedFrame]) -> None:
        actors = make_actors(settings)
        response = actors.client.post(
            f"/api/vehicles/{actors.vehicle_id}/frames",
            params={"t": 1},
            content=frames[0].data,
            headers={**actors.auth("vehicle"), "Content-Type": "image/png"},
        )
        assert response.status_code == 409 and "has no map" in response.json()["detail"]


class TestMotion:
    def test_a_vehicle_without_a_camera_never_reports_odometry(
        self, actors: Actors, frames: list[RecordedFrame]
    ) -> None:
        viewer = actors.auth("viewer")
        with actors.client.websocket_connect("/api/live", headers=viewer) as ws:
            assert ws.receive_json()["type"] == "snapshot"
            answers = [post(actors, f) for f in frames[:20]]
            messages = [ws.receive_json() for _ in answers]
        history = actors.client.get(f"/api/vehicles/{actors.vehicle_id}/positions", headers=viewer).json()
        for rows in (answers, messages, history):
            assert [r["odometry"] for r in rows] == [False] * len(answers)
            assert all(r["speed_mps"] is None and isinstance(r["moving"], bool) for r in rows)
            assert all(r["yaw"] is None or math.isfinite(r["yaw"]) for r in rows)
        assert [m["confidence"] for m in messages] == [a["confidence"] for a in answers]
        assert [h["confidence"] for h in history] == [a["confidence"] for a in answers]

    def test_a_vehicle_with_a_camera_reports_its_motion(
        self, actors: Actors, frames: list[RecordedFrame], tiny_site_dir: Path
    ) -> None:
        give_drive_camera(actors, tiny_site_dir)
        answers = [post(actors, f) for f in frames[:60]]
        assert [a["status"] for a in answers] == ["processed"] * len(answers)
        measured = [a for a in answers if a["odometry"]]
        assert len(measured) >= len(answers) // 2
        assert all(a["speed_mps"] is not None and math.isfinite(a["speed_mps"]) for a in measured)
        history = actors.client.get(
            f"/api/vehicles/{actors.vehicle_id}/positions", headers=actors.auth("viewer")
        ).json()
        assert [(h["odometry"], h["speed_mps"], h["yaw"], h["moving"]) for h in history] == [
            (a["odometry"], a["speed_mps"], a["yaw"], a["moving"]) for a in answers
        ]


FRAME_STATUSES = ("processed", "skipped", "out_of_order")


def _frames_counted(status: str) -> float:
    return LIVE_REGISTRY.get_sample_value("driftmap_live_frames_total", {"status": status}) or 0.0


class TestOverload:
    def test_a_burst_skips_stale_frames_in_order_and_counts_them(
        self, built: Path, frames: list[RecordedFrame]
    ) -> None:
        settings = Settings(data_dir=built)
        storage = Storage.open(settings)
        with storage.db.session() as session:
            vehicle, _token = vehicle_service.create_vehicle(
                session, "burst", site_service.get_site(session, "tiny").id
            )
            vid, site_id = vehicle.id, vehicle.site_id
        live = LiveService(
            settings,
            storage,
            position_message=position_message,
            event_message=event_message,
            queue_depth=1,
            processes=1,
        )
        burst = [(f.t, f.data) for f in frames[:12]]
        counted = {status: _frames_counted(status) for status in FRAME_STATUSES}

        async def run() -> list:  # type: ignore[type-arg]
            first = await asyncio.gather(*(live.submit(vid, "burst", site_id, t, g) for t, g in burst[:6]))
            second = await asyncio.gather(*(live.submit(vid, "burst", site_id, t, g) for t, g in burst[6:]))
            late = await live.submit(vid, "burst", site_id, burst[3][0], burst[3][1])
            tail = await live.submit(vid, "burst", site_id, frames[12].t, frames[12].data)
            return [*first, *second, late, tail]

        outcomes = asyncio.run(run())
        live.close()
        assert [o.t for o in outcomes[:12]] == [t for t, _g in burst]  # one answer per frame, in order
        statuses = [o.status for o in outcomes]
        assert statuses[-2:] == ["out_of_order", "processed"]
        processed = [o.t for o in outcomes if o.status == "processed"]
        assert processed == sorted(processed) and processed[-2:] == [burst[-1][0], frames[12].t]
        assert statuses[:12].count("skipped") >= 8  # one frame runs, one waits: a burst of 6 keeps 1-2
        assert statuses[5] == statuses[11] == "processed"  # the newest frame of a burst is always processed
        assert {status: _frames_counted(status) - counted[status] for status in FRAME_STATUSES} == {
            status: statuses.count(status) for status in FRAME_STATUSES
        }  # GET /metrics's driftmap_live_frames_total
        with storage.db.session() as session:
            state = session.get(VehicleLiveState, vid)
            assert state is not None
            assert (state.processed, state.skipped) == (len(processed), statuses.count("skipped"))
            assert state.out_of_order == 1
        storage.close()

    def test_frames_arriving_shuffled_are_never_processed_backwards(
        self, built: Path, frames: list[RecordedFrame]
    ) -> None:
        settings = Settings(data_dir=built)
        storage = Storage.open(settings)
        with storage.db.session() as session:
            vehicle, _token = vehicle_service.create_vehicle(
                session, "shuffled", site_service.get_site(session, "tiny").id
            )
            vid, site_id = vehicle.id, vehicle.site_id
        live = LiveService(
            settings,
            storage,
            position_message=position_message,
            event_message=event_message,
            queue_depth=1,
            processes=1,
        )
        order = [3, 1, 2, 0, 5, 4]

        async def run() -> list:  # type: ignore[type-arg]
            return await asyncio.gather(
                *(live.submit(vid, "s", site_id, frames[i].t, frames[i].data) for i in order)
            )

        outcomes = asyncio.run(run())
        live.close()
        storage.close()
        status = {o.t: o.status for o in outcomes}
        processed = [o.t for o in sorted(outcomes, key=lambda o: o.seq or 0) if o.status == "processed"]
        assert processed == sorted(processed) and frames[5].t in processed
        assert set(status.values()) <= {"processed", "skipped", "out_of_order"} and len(status) == len(order)


class TestWorkerProcesses:
    def test_a_killed_localiser_process_costs_one_frame_and_is_restarted(
        self, built: Path, frames: list[RecordedFrame]
    ) -> None:
        settings = Settings(data_dir=built)
        storage = Storage.open(settings)
        with storage.db.session() as session:
            vehicle, _token = vehicle_service.create_vehicle(
                session, "crash", site_service.get_site(session, "tiny").id
            )
            vid, site_id = vehicle.id, vehicle.site_id
        live = LiveService(
            settings, storage, position_message=position_message, event_message=event_message, processes=1
        )

        async def run() -> list[str]:
            first = await live.submit(vid, "crash", site_id, frames[0].t, frames[0].data)
            pool = live.workers._pools[0]
            assert pool is not None
            for process in list(pool._processes.values()):  # the worker dies (OOM killer, segfault, ...)
                os.kill(process.pid, signal.SIGKILL)
            statuses = [first.status]
            for f in frames[1:3]:
                try:
                    statuses.append((await live.submit(vid, "crash", site_id, f.t, f.data)).status)
                except ConflictError as exc:
                    assert "died" in str(exc)
                    statuses.append("error")
            return statuses

        statuses = asyncio.run(run())
        live.close()
        with storage.db.session() as session:
            state = session.get(VehicleLiveState, vid)
            assert state is not None and state.processed == statuses.count("processed")
        storage.close()
        assert statuses[0] == "processed" and statuses[-1] == "processed"
        assert statuses.count("error") <= 1


class TestHub:
    def test_a_full_queue_marks_the_watcher_for_a_resync(self) -> None:
        async def run() -> tuple[bool, bool, int]:
            hub = InMemoryHub(queue_size=1)
            watcher = hub.subscribe()
            await hub.publish({"seq": 1})
            await hub.publish({"seq": 2})
            overflowed = watcher.overflowed
            watcher.drain()
            hub.unsubscribe(watcher)
            await hub.publish({"seq": 3})
            return overflowed, watcher.overflowed, watcher.queue.qsize()

        assert asyncio.run(run()) == (True, False, 0)


def _framed(frame: RecordedFrame) -> bytes:
    return struct.pack(">d", frame.t) + frame.data


class TestStream:
    def test_frames_over_a_websocket_each_get_one_answer(
        self, actors: Actors, frames: list[RecordedFrame]
    ) -> None:
        url = f"/api/vehicles/{actors.vehicle_id}/stream"
        with actors.client.websocket_connect(url, headers=actors.auth("vehicle")) as ws:
            for f in frames[:10]:
                ws.send_bytes(_framed(f))
            answers = [ws.receive_json() for _ in range(10)]
            ws.send_text("hello")
            error = ws.receive_json()
            ws.send_bytes(struct.pack(">d", 99.0) + b"garbage")
            garbage = ws.receive_json()
            ws.send_bytes(_framed(frames[10]))
            after = ws.receive_json()
        assert sorted(a["t"] for a in answers) == [f.t for f in frames[:10]]
        assert {a["status"] for a in answers} <= {"processed", "skipped"}
        processed = [a["t"] for a in answers if a["status"] == "processed"]
        assert processed and max(processed) == frames[9].t
        assert error["status"] == "error" and error["code"] == 400 and error["field"] == "message"
        assert garbage["code"] == 422 and garbage["t"] == 99.0
        assert after["status"] == "processed" and after["t"] == frames[10].t

    def test_a_rotated_token_closes_the_stream(
        self, actors: Actors, frames: list[RecordedFrame], monkeypatch: pytest.MonkeyPatch
    ) -> None:
        monkeypatch.setattr(live_api, "TOKEN_RECHECK_S", 0.0)  # check at every message
        url = f"/api/vehicles/{actors.vehicle_id}/stream"
        with actors.client.websocket_connect(url, headers=actors.auth("vehicle")) as ws:
            ws.send_bytes(_framed(frames[0]))
            assert ws.receive_json()["status"] == "processed"
            rotated = actors.client.post(
                f"/api/vehicles/{actors.vehicle_id}/token", headers=actors.auth("admin")
            )
            assert rotated.status_code == 200, rotated.text
            ws.send_bytes(_framed(frames[1]))
            with pytest.raises(WebSocketDisconnect) as closed:
                ws.receive_json()
        assert closed.value.code == 4401


class TestWatch:
    def test_snapshot_then_updates_then_resume(self, actors: Actors, frames: list[RecordedFrame]) -> None:
        viewer = actors.auth("viewer")
        with actors.client.websocket_connect("/api/live", headers=viewer) as ws:
            snapshot = ws.receive_json()
            assert snapshot["type"] == "snapshot" and snapshot["seq"] == 0
            assert {v["vehicle"] for v in snapshot["vehicles"]} == {"lhd-1", "lhd-2"}
            assert all(v["stale"] and v["position"] is None for v in snapshot["vehicles"])
            answers = [post(actors, f) for f in frames[:3]]
            updates = [ws.receive_json() for _ in range(3)]
        assert [u["type"] for u in updates] == ["position"] * 3
        assert [u["seq"] for u in updates] == [a["seq"] for a in answers]
        assert [(u["x"], u["y"]) for u in updates] == [(a["x"], a["y"]) for a in answers]
        post(actors, frames[3])
        with actors.client.websocket_connect(f"/api/live?since={answers[0]['seq']}", headers=viewer) as ws:
            snapshot = ws.receive_json()
            replay = [ws.receive_json() for _ in range(3)]
        mine = next(v for v in snapshot["vehicles"] if v["vehicle_id"] == actors.vehicle_id)
        assert not mine["stale"] and mine["position"]["t"] == frames[3].t
        assert [m["t"] for m in replay] == [f.t for f in frames[1:4]]

    def test_watchers_get_every_position_once_in_order_with_a_tiny_queue(
        self, actors: Actors, frames: list[RecordedFrame]
    ) -> None:
        actors.app.state.live.hub.queue_size = 1  # a watcher that falls behind resyncs from the history
        with actors.client.websocket_connect("/api/live", headers=actors.auth("viewer")) as ws:
            assert ws.receive_json()["type"] == "snapshot"
            answers = [post(actors, f) for f in frames[:8]]
            updates = [ws.receive_json() for _ in range(8)]
        assert [u["seq"] for u in updates] == [a["seq"] for a in answers]

    def test_a_silent_vehicle_turns_stale_and_keeps_its_last_position(
        self, built: Path, frames: list[RecordedFrame]
    ) -> None:
        settings = Settings(data_dir=built, stale_after_s=0.0, live_processes=1, event_check_every_s=0.0)
        actors = make_actors(settings, site_name="tiny")  # (no stale events in the way of the stale message)
        with actors.client:
            answer = post(actors, frames[0])
            latest = actors.client.get("/api/positions/latest", headers=actors.auth("viewer")).json()
            mine = next(v for v in latest if v["vehicle_id"] == actors.vehicle_id)
            assert mine["stale"] and mine["position"]["seq"] == answer["seq"]
            with actors.client.websocket_connect("/api/live", headers=actors.auth("viewer")) as ws:
                assert ws.receive_json()["type"] == "snapshot"
                post(actors, frames[1])
                assert ws.receive_json()["type"] == "position"
                stale = ws.receive_json()
        assert stale == {
            "type": "stale",
            "vehicle_id": actors.vehicle_id,
            "received_at": stale["received_at"],
        }
