"""Live state across API processes: two live services on one database, the Redis hub and frame store, and two
real ``driftmap serve`` processes sharing one data directory and one redis-server.

A vehicle's localiser state is a database row (with a revision), so frames of one vehicle posted to two
processes in turn must give exactly what one process gives. Watchers and latest frames go through Redis, so a
watcher on one process sees positions localised on another. Runs against a real redis-server.
"""

from __future__ import annotations

import asyncio
import json
import re
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import httpx
import pytest
import redis
import websockets

from driftmap.api.schemas_live import event_message, position_message
from driftmap.config import Settings
from driftmap.live.hub import RedisHub, Subscription
from driftmap.live.ingest import LiveService
from driftmap.live.latest_frames import RedisFrames
from driftmap.live.localise import FrameOutcome
from driftmap.services import sites as site_service
from driftmap.services import users as user_service
from driftmap.services import vehicles as vehicle_service
from driftmap.store.access_models import VehicleLiveState, VehiclePosition
from driftmap.store.storage import Storage
from tests.api.access_helpers import (
    RecordedFrame,
    localisation_drive,
    make_actors,
    recorded_frames,
)
from tests.processes import driftmap_env, start_server, stop
from tests.redis_server import running_redis

FRAMES = 24
RECEIVE_DEADLINE_S = 10.0  # a published message must reach a watcher of another hub within this
START_DEADLINE_S = 90.0
LATENCY_MESSAGES = 200


@pytest.fixture
def redis_url(tmp_path: Path) -> Iterator[str]:
    """A private redis-server for this test (skipped without redis-server)."""
    with running_redis(tmp_path) as url:
        yield url


@pytest.fixture
def frames(tiny_site_dir: Path) -> list[RecordedFrame]:
    return recorded_frames(localisation_drive(tiny_site_dir), FRAMES)


def _vehicles(storage: Storage, *names: str) -> list[tuple[int, int]]:
    """(vehicle id, site id) of new vehicles of the tiny site."""
    made = []
    with storage.db.session() as session:
        site_id = site_service.get_site(session, "tiny").id
        for name in names:
            vehicle, _token = vehicle_service.create_vehicle(session, name, site_id)
            made.append((vehicle.id, site_id))
    return made


def _estimate(outcome: FrameOutcome) -> tuple[object, ...]:
    return outcome.t, outcome.node, outcome.x, outcome.y, outcome.confidence, outcome.matched, outcome.lost


@pytest.mark.slow
class TestTwoServicesOnOneDatabase:
    def test_frames_alternating_between_two_services_equal_one_service(
        self, built: Path, frames: list[RecordedFrame]
    ) -> None:
        settings = Settings(data_dir=built)
        storage = Storage.open(settings)
        (shared, site_id), (alone, _site) = _vehicles(storage, "shared", "alone")
        first, second, single = (
            LiveService(
                settings, storage, position_message=position_message, event_message=event_message, processes=1
            )
            for _ in range(3)
        )

        async def run() -> tuple[list[FrameOutcome], list[FrameOutcome]]:
            both = [
                await (first if k % 2 == 0 else second).submit(shared, "shared", site_id, f.t, f.data)
                for k, f in enumerate(frames)
            ]
            one = [await single.submit(alone, "alone", site_id, f.t, f.data) for f in frames]
            return both, one

        both, one = asyncio.run(run())
        for live in (first, second, single):
            live.close()
        with storage.db.session() as session:
            rows = (
                session.query(VehiclePosition).filter_by(vehicle_id=shared).order_by(VehiclePosition.id).all()
            )
            state = session.get(VehicleLiveState, shared)
            assert state is not None
            assert (state.processed, state.skipped, state.out_of_order) == (FRAMES, 0, 0)
        storage.close()
        assert [o.status for o in both] == ["processed"] * FRAMES
        assert [o.processed for o in both] == list(range(1, FRAMES + 1))
        assert [r.t_s for r in rows] == [f.t for f in frames]  # once each, in order
        assert [_estimate(o) for o in both] == [_estimate(o) for o in one]

    def test_frames_racing_into_two_services_are_never_processed_twice_or_backwards(
        self, built: Path, frames: list[RecordedFrame]
    ) -> None:
        settings = Settings(data_dir=built)
        storage = Storage.open(settings)
        [(vid, site_id)] = _vehicles(storage, "raced")
        first, second = (
            LiveService(
                settings, storage, position_message=position_message, event_message=event_message, processes=1
            )
            for _ in range(2)
        )

        async def run() -> list[FrameOutcome]:
            tasks = []
            for k, f in enumerate(frames[:12]):
                live = first if k % 2 == 0 else second
                tasks.append(asyncio.create_task(live.submit(vid, "raced", site_id, f.t, f.data)))
                await asyncio.sleep(0.02)  # frames arrive faster than they are localised
            return list(await asyncio.gather(*tasks))

        outcomes = asyncio.run(run())
        first.close()
        second.close()
        with storage.db.session() as session:
            rows = session.query(VehiclePosition).filter_by(vehicle_id=vid).order_by(VehiclePosition.id).all()
            state = session.get(VehicleLiveState, vid)
            assert state is not None
            counts = state.processed, state.skipped, state.out_of_order
        storage.close()
        statuses = [o.status for o in outcomes]
        processed = [o.t for o in outcomes if o.status == "processed"]
        assert [r.t_s for r in rows] == sorted(processed) == sorted(set(processed))
        assert outcomes[-1].status == "processed"  # the newest frame always is
        assert counts == tuple(statuses.count(s) for s in ("processed", "skipped", "out_of_order"))


async def _receive(subscription: Subscription, count: int) -> list[dict[str, object]]:
    return [await asyncio.wait_for(subscription.queue.get(), RECEIVE_DEADLINE_S) for _ in range(count)]


class TestRedisHub:
    def test_a_watcher_of_one_hub_gets_what_another_publishes_in_vehicle_order(self, redis_url: str) -> None:
        async def run() -> tuple[list[dict[str, object]], int, bool]:
            a, b = RedisHub(redis_url), RedisHub(redis_url)
            await a.start()
            await b.start()
            watcher = a.subscribe()
            await b.publish({"type": "position", "vehicle_id": 1, "seq": 5})
            await a.publish({"type": "position", "vehicle_id": 1, "seq": 4})  # overtaken: not published
            await b.publish({"type": "position", "vehicle_id": 2, "seq": 3})  # another vehicle: published
            await a.publish({"type": "position", "vehicle_id": 1, "seq": 6})
            got = await _receive(watcher, 3)
            await asyncio.sleep(0.2)
            extra = watcher.queue.qsize()
            a.unsubscribe(watcher)
            await b.publish({"type": "position", "vehicle_id": 1, "seq": 7})
            await asyncio.sleep(0.2)
            await a.close()
            await b.close()
            return got, extra + watcher.queue.qsize(), watcher.overflowed

        got, extra, overflowed = asyncio.run(run())
        assert [(m["vehicle_id"], m["seq"]) for m in got] == [(1, 5), (2, 3), (1, 6)]
        assert extra == 0 and not overflowed

    def test_two_hubs_racing_on_one_vehicle_never_deliver_it_backwards(self, redis_url: str) -> None:
        async def run() -> tuple[list[int], int]:
            a, b, watched = RedisHub(redis_url), RedisHub(redis_url), RedisHub(redis_url)
            for hub in (a, b, watched):
                await hub.start()
            watcher = watched.subscribe()

            async def send(hub: RedisHub, seqs: range) -> None:
                for seq in seqs:  # each hub lags the other now and then, as two API processes would
                    await hub.publish({"type": "position", "vehicle_id": 1, "seq": seq})
                    if seq % 7 == 0:
                        await asyncio.sleep(0.001)

            await asyncio.gather(send(a, range(1, 400, 2)), send(b, range(2, 401, 2)))
            await b.publish({"type": "position", "vehicle_id": 1, "seq": 401})
            got: list[int] = []
            while not got or got[-1] != 401:
                got.append(int(str((await asyncio.wait_for(watcher.queue.get(), RECEIVE_DEADLINE_S))["seq"])))
            skipped = a.skipped + b.skipped
            for hub in (a, b, watched):
                await hub.close()
            return got, skipped

        got, skipped = asyncio.run(run())
        print(f"racing publishers: {skipped} of 401 positions overtaken and not published")
        assert got == sorted(set(got))  # strictly increasing
        assert len(got) + skipped == 401

    def test_overflow_and_a_lost_connection_mark_watchers_for_a_resync(self, redis_url: str) -> None:
        async def run() -> tuple[bool, bool, dict[str, object]]:
            a, b = RedisHub(redis_url, queue_size=1), RedisHub(redis_url)
            await a.start()
            await b.start()
            watcher = a.subscribe()
            for seq in (1, 2, 3):
                await b.publish({"type": "position", "vehicle_id": 1, "seq": seq})
            deadline = time.monotonic() + RECEIVE_DEADLINE_S
            while not watcher.overflowed:
                assert time.monotonic() < deadline, "the full queue was never marked"
                await asyncio.sleep(0.02)
            overflowed = watcher.overflowed
            watcher.drain()
            cleared = not watcher.overflowed
            killer = redis.Redis.from_url(redis_url)
            assert killer.client_kill_filter(_type="pubsub") >= 1  # Redis drops the listener's connection
            killer.close()
            while not watcher.overflowed:
                assert time.monotonic() < deadline, "the reconnection was not noticed"
                await asyncio.sleep(0.02)
            watcher.drain()
            await b.publish({"type": "position", "vehicle_id": 1, "seq": 4})  # delivered after reconnecting
            [after] = await _receive(watcher, 1)
            await a.close()
            await b.close()
            return overflowed, cleared, after

        overflowed, cleared, after = asyncio.run(run())
        assert overflowed and cleared and after["seq"] == 4

    def test_latency_between_two_hubs(self, redis_url: str) -> None:
        """Publish on one hub, receive on another: prints the median and 99th percentile, milliseconds."""

        async def run() -> list[float]:
            a, b = RedisHub(redis_url), RedisHub(redis_url)
            await a.start()
            await b.start()
            watcher = a.subscribe()
            delays = []
            for seq in range(1, LATENCY_MESSAGES + 1):
                sent = time.perf_counter()
                await b.publish({"type": "position", "vehicle_id": 1, "seq": seq, "x": 1.0, "y": 2.0})
                await _receive(watcher, 1)
                delays.append((time.perf_counter() - sent) * 1000.0)
            await a.close()
            await b.close()
            return sorted(delays)

        delays = asyncio.run(run())
        median, p99 = delays[len(delays) // 2], delays[int(0.99 * len(delays))]
        print(f"redis hub publish -> other hub's watcher: median {median:.2f} ms, p99 {p99:.2f} ms")
        assert median < 100.0


class TestWatcherAcrossProcesses:
    def test_positions_of_two_vehicles_out_of_seq_order_both_reach_a_watcher(
        self, tmp_path: Path, redis_url: str
    ) -> None:
        """Another process publishes vehicle B's seq 11 before vehicle A's seq 10: a watcher gets both."""
        actors = make_actors(Settings(data_dir=tmp_path / "data", redis_url=redis_url, live_processes=1))
        a, b = actors.vehicle_id, actors.other_vehicle_id
        received_at = datetime.now(UTC).isoformat()  # recent: no stale message in between

        def position(vehicle_id: int, seq: int) -> dict[str, object]:
            return {"type": "position", "vehicle_id": vehicle_id, "seq": seq, "received_at": received_at}

        async def publish(*messages: dict[str, object]) -> None:
            other = RedisHub(redis_url)  # the hub of another API process
            await other.start()
            for message in messages:
                await other.publish(message)
            await other.close()

        with actors.client, actors.client.websocket_connect("/api/live", headers=actors.auth("viewer")) as ws:
            assert ws.receive_json()["type"] == "snapshot"
            asyncio.run(publish(position(b, 11), position(a, 10), position(a, 12)))
            got = [ws.receive_json() for _ in range(3)]
        assert [(m["vehicle_id"], m["seq"]) for m in got] == [(b, 11), (a, 10), (a, 12)]


class TestRedisFrames:
    def test_any_store_serves_the_newest_frame_until_it_expires(self, redis_url: str) -> None:
        async def run() -> tuple[object, object, object, object]:
            a, b = RedisFrames(redis_url, ttl_s=1), RedisFrames(redis_url, ttl_s=1)
            await a.start()
            await b.start()
            before = await b.get(7)
            await a.put(7, 2.5, b"\x89PNG newer")
            await b.put(7, 1.5, b"\x89PNG older")  # a slower process never replaces a newer frame
            kept = await b.get(7)
            await b.put(8, 0.1, b"\xff\xd8 other")
            other = await a.get(8)
            deadline = time.monotonic() + 10.0
            while (gone := await a.get(7)) is not None and time.monotonic() < deadline:
                await asyncio.sleep(0.1)
            await a.close()
            await b.close()
            return before, kept, other, gone

        before, kept, other, gone = asyncio.run(run())
        assert before is None and gone is None
        assert kept == (2.5, b"\x89PNG newer") and other == (0.1, b"\xff\xd8 other")


@dataclass(frozen=True)
class Fleet:
    """Servers on one data dir and one Redis, a viewer's token and a vehicle with its token."""

    bases: list[str]
    viewer: str
    vehicle_id: int
    vehicle_token: str


def _env(data: Path, redis: str | None) -> dict[str, str]:
    """A ``driftmap`` subprocess's environment: ``data``, the run's database, one localiser, ``redis``."""
    return driftmap_env(data, live_processes="1", **({"redis_url": redis} if redis is not None else {}))


@contextmanager
def _fleet(data: Path, redis: str, tmp_path: Path, *serves: tuple[str, ...]) -> Iterator[Fleet]:
    """Start one ``driftmap serve`` per argument tuple on ``data`` and ``redis``; stop them afterwards."""
    storage = Storage.open(Settings(data_dir=data))
    with storage.db.session() as session:
        user_service.create_user(session, "ops", "long-password", "viewer")
        site_id = site_service.get_site(session, "tiny").id
        vehicle, token = vehicle_service.create_vehicle(session, "lhd", site_id)
        vehicle_id = vehicle.id
    storage.close()
    started: list[subprocess.Popen[bytes]] = []
    bases = []
    try:
        for k, extra in enumerate(serves):
            process, base = start_server(
                _env(data, redis), tmp_path / f"serve-{k}.log", *extra, deadline_s=START_DEADLINE_S
            )
            started.append(process)
            bases.append(base)
        login = httpx.post(
            f"{bases[0]}/api/auth/login", json={"username": "ops", "password": "long-password"}
        )
        yield Fleet(bases, login.json()["access_token"], vehicle_id, token)
    finally:
        for process in started:
            stop(process)


@pytest.fixture
def two_servers(built: Path, redis_url: str, tmp_path: Path) -> Iterator[Fleet]:
    """Two ``driftmap serve`` processes on one data dir and one Redis."""
    with _fleet(built, redis_url, tmp_path, (), ()) as fleet:
        yield fleet


async def _post_and_watch(
    fleet: Fleet, frames: list[RecordedFrame], watch_base: str
) -> tuple[list[dict[str, object]], list[dict[str, object]], list[float]]:
    """Post ``frames`` in turn to each server (a new connection each), watching on ``watch_base``; returns the
    answers, the watcher's messages and each message's delay after its answer, milliseconds."""
    mine = {"Authorization": f"Bearer {fleet.vehicle_token}", "Content-Type": "image/png"}
    url = f"/api/vehicles/{fleet.vehicle_id}/frames"
    live_url = watch_base.replace("http", "ws") + "/api/live"
    answers, updates, delays = [], [], []
    viewer = {"Authorization": f"Bearer {fleet.viewer}"}
    async with websockets.connect(live_url, additional_headers=viewer) as live:
        assert json.loads(await live.recv())["type"] == "snapshot"
        for k, f in enumerate(frames):
            async with httpx.AsyncClient(timeout=60.0) as client:
                base = fleet.bases[k % len(fleet.bases)]
                response = await client.post(base + url, params={"t": f.t}, content=f.data, headers=mine)
            assert response.status_code == 200, response.text
            answered = time.perf_counter()
            answers.append(response.json())
            updates.append(json.loads(await asyncio.wait_for(live.recv(), RECEIVE_DEADLINE_S)))
            delays.append((time.perf_counter() - answered) * 1000.0)
    return answers, updates, delays


@pytest.mark.slow
class TestTwoServeProcesses:
    def test_a_watcher_on_one_server_sees_frames_posted_to_the_other(
        self, two_servers: Fleet, frames: list[RecordedFrame]
    ) -> None:
        fleet = two_servers
        base_a, base_b = fleet.bases
        answers, updates, delays = asyncio.run(_post_and_watch(fleet, frames[:10], base_a))
        assert [a["status"] for a in answers] == ["processed"] * 10
        assert [u["seq"] for u in updates] == [a["seq"] for a in answers]
        assert [u["t"] for u in updates] == [f.t for f in frames[:10]]
        print(f"answer -> watcher message (frames alternating between two servers): max {max(delays):.1f} ms")

        viewer = {"Authorization": f"Bearer {fleet.viewer}"}
        latest_url = f"/api/vehicles/{fleet.vehicle_id}/frames/latest"
        latest = httpx.get(base_a + latest_url, headers=viewer)
        assert latest.status_code == 200 and latest.content == frames[9].data
        assert float(latest.headers["x-frame-t"]) == frames[9].t
        response = httpx.post(
            f"{base_b}/api/vehicles/{fleet.vehicle_id}/frames",
            params={"t": frames[10].t},
            content=frames[10].data,
            headers={"Authorization": f"Bearer {fleet.vehicle_token}", "Content-Type": "image/png"},
            timeout=60.0,
        )
        assert response.json()["status"] == "processed"
        latest = httpx.get(base_a + latest_url, headers=viewer)
        assert latest.content == frames[10].data and float(latest.headers["x-frame-t"]) == frames[10].t


@pytest.mark.slow
class TestServeWorkers:
    def test_several_api_processes_without_redis_are_refused(self, tmp_path: Path) -> None:
        done = subprocess.run(
            [sys.executable, "-m", "driftmap", "serve", "--workers", "2"],
            env=_env(tmp_path / "data", None),
            capture_output=True,
            timeout=120,
            check=False,
        )
        assert done.returncode != 0 and "DRIFTMAP_REDIS_URL" in done.stderr.decode()

    def test_api_processes_on_one_port_share_watchers(
        self, built: Path, redis_url: str, tmp_path: Path, frames: list[RecordedFrame]
    ) -> None:
        with _fleet(built, redis_url, tmp_path, ("--workers", "2")) as fleet:
            answers, updates, _delays = asyncio.run(_post_and_watch(fleet, frames[:8], fleet.bases[0]))
            assert [u["seq"] for u in updates] == [a["seq"] for a in answers]
            log = (tmp_path / "serve-0.log").read_text()
            assert len(set(re.findall(r"Started server process \[(\d+)\]", log))) == 2, log
