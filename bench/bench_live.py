"""Load benchmark of live localisation: simulated vehicles post real frames to a real server over loopback.

Simulates the tiny (or small) site, imports it, builds a FAST map, starts ``driftmap serve --no-worker`` on a
free port and registers ``--vehicles`` vehicles. Each vehicle replays the site's localisation drive as a
camera would: one frame every 1/``--fps`` seconds, posted without waiting for the previous answer (open
loop), to ``POST /api/vehicles/{id}/frames``. Prints the p50 and p99 latency of the frame endpoint, the
answers by status, and checks from the stored history that no frame was lost, reordered or processed twice:
per vehicle, processed + skipped + out of order equals frames sent and the stored positions' ``t`` strictly
increase, and the share of each vehicle's frames that was processed (fair scheduling: min/max near 1). Each
vehicle is given the drive's camera, so its frames run the ground-plane odometry too. The baseline is the same frames localised in this process without HTTP (decode + localiser step +
database write), one vehicle at a time; the ratio of the HTTP p50 to it is the cost of the server.
Target (issue 5): 5 vehicles at 10 frames/s, p99 <= 150 ms.

Usage: ``.venv/bin/python bench/bench_live.py [--vehicles 5] [--fps 10] [--seconds 20] [--size tiny]``
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import os
import statistics
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import httpx
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' helpers

from tests.processes import start_server, stop

from driftmap.config import Settings
from driftmap.core.mapping.pipeline import MAPPING_FAST
from driftmap.formats.drive_folder import iter_frame_images, read_drive_folder
from driftmap.formats.drive_json import camera_to_json
from driftmap.formats.frame_images import decode_gray
from driftmap.live import localise as live_localise
from driftmap.services import drives as drive_service
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.services import users as user_service
from driftmap.services import vehicles as vehicle_service
from driftmap.sim import simulate_site
from driftmap.store.storage import Storage

TARGET_P99_MS = 150.0
MAX_IN_FLIGHT = 8  # frames a vehicle keeps waiting for an answer


async def log_in(base: str) -> dict[str, str]:
    """The benchmark admin's authorisation header."""
    async with httpx.AsyncClient(base_url=base, timeout=30.0) as client:
        login = await client.post("/api/auth/login", json={"username": "bench", "password": "bench-password"})
    return {"Authorization": f"Bearer {login.json()['access_token']}"}


def prepare(
    work: Path, size: str, database_url: str | None = None
) -> tuple[Path, list[tuple[float, bytes]], dict[str, Any]]:
    """A data dir with the simulated site and its map (in ``database_url``'s database if given, else the
    embedded SQLite one); the localisation drive's (t, PNG bytes) and camera block (the vehicles are given
    it, so they are localised with odometry, as the product's default)."""
    site_dir = work / "site"
    simulate_site(site_dir, seed=3, size=size, obscurants=False)
    data = work / "data"
    storage = Storage.open(Settings(data_dir=data, database_url=database_url))
    with storage.blobs.batch() as batch, storage.db.session() as session:
        site = site_service.create_site(session, "bench")
        site_service.add_survey_map(
            session, batch, site, (site_dir / "survey.dxf").read_bytes(), "survey.dxf"
        )
    folders = drive_service.drive_folders_in(site_dir / "drives")
    for folder in (f for f in folders if f.name.startswith("map")):
        with storage.blobs.batch() as batch, storage.db.session() as session:
            drive_service.import_drive(session, batch, site_service.get_site(session, "bench"), folder)
    with storage.blobs.batch() as batch, storage.db.session() as session:
        map_service.build_site_map(
            session, storage.blobs, batch, site_service.get_site(session, "bench"), MAPPING_FAST
        )
        user_service.create_user(session, "bench", "bench-password", "admin")
    storage.close()
    loc = read_drive_folder(next(f for f in folders if f.name.startswith("loc")))
    return data, [(row.t_s, blob) for row, blob in iter_frame_images(loc)], camera_to_json(loc.meta.camera)


def baseline_ms(
    data: Path,
    frames: list[tuple[float, bytes]],
    count: int,
    camera: dict[str, Any],
    database_url: str | None = None,
) -> float:
    """Median ms per frame localised in-process (decode, odometry and step, database write), one vehicle."""
    storage = Storage.open(Settings(data_dir=data, database_url=database_url))
    with storage.db.session() as session:
        vehicle, _token = vehicle_service.create_vehicle(session, "baseline", 1)
        vehicle_service.set_camera(session, vehicle, camera)
        vid = vehicle.id
    maps, slot, times = live_localise.LiveMaps(), None, []
    for t_s, blob in frames[:count]:
        t0 = time.perf_counter()
        _outcome, slot = live_localise.localise_live_frame(
            storage.db, storage.blobs, maps, vid, t_s, decode_gray(blob), (0, 0), slot
        )
        times.append((time.perf_counter() - t0) * 1e3)
    storage.close()
    return statistics.median(times[1:])


@contextlib.contextmanager
def serving(
    data: Path, work: Path, *options: str, env: dict[str, str] | None = None
) -> Iterator[tuple[str, int]]:
    """``driftmap serve`` on ``data`` at a free loopback port (``env``: more of its environment), logging to
    ``work/serve.log``; yields its base URL and process id once ``/api/health`` answers 200, and terminates
    it on leaving."""
    env = {**os.environ, "DRIFTMAP_DATA_DIR": str(data), **(env or {})}
    server, base = start_server(env, work / "serve.log", *options)
    try:
        yield base, server.pid
    finally:
        stop(server)


AnswerSink = Callable[[float, str, float | None], None]
"""Told of each frame a vehicle sends: its ``t``, the answer's status (or ``not sent``, or the transport
error's name) and the answer's latency in milliseconds (None when not sent)."""


async def add_vehicle(
    client: httpx.AsyncClient, admin: dict[str, str], name: str, camera: dict[str, Any]
) -> tuple[int, dict[str, str]]:
    """A new vehicle of site 1 with ``camera``; returns its id and its frame-posting headers."""
    made = (await client.post("/api/vehicles", json={"name": name, "site_id": 1}, headers=admin)).json()
    await client.put(f"/api/vehicles/{made['id']}/camera", json=camera, headers=admin)
    return int(made["id"]), {"Authorization": f"Bearer {made['token']}", "Content-Type": "image/png"}


async def stream_frames(
    client: httpx.AsyncClient,
    vehicle_id: int,
    headers: dict[str, str],
    frames: list[tuple[float, bytes]],
    k: int,
    count: int,
    fps: float,
    start: float,
    answered: AnswerSink,
) -> None:
    """Post ``count`` frames at ``fps`` from ``start`` (``time.perf_counter``), as vehicle number ``k``
    (which frame of ``frames`` it starts at), telling ``answered`` of each.

    Open loop, like a vehicle computer: it keeps at most ``MAX_IN_FLIGHT`` frames waiting for an answer and
    drops a new frame while that many wait (``not sent``); a client that queued without bound would measure
    its own backlog, not the server. ``client`` should be the vehicle's own, with ``MAX_IN_FLIGHT``
    connections."""
    url = f"/api/vehicles/{vehicle_id}/frames"
    running: set[asyncio.Task[None]] = set()

    async def post(t_s: float, blob: bytes) -> None:
        t0 = time.perf_counter()
        try:
            response = await client.post(url, params={"t": t_s}, content=blob, headers=headers)
            status = str(response.json().get("status", response.status_code))
        except httpx.HTTPError as e:
            status = type(e).__name__
        answered(t_s, status, (time.perf_counter() - t0) * 1e3)

    for i in range(count):
        delay = start + i / fps - time.perf_counter()
        if delay > 0:
            await asyncio.sleep(delay)
        t_s = round(i / fps, 3)
        if len(running) >= MAX_IN_FLIGHT:
            answered(t_s, "not sent", None)
            continue
        task = asyncio.create_task(post(t_s, frames[(i + 37 * k) % len(frames)][1]))
        running.add(task)
        task.add_done_callback(running.discard)
    await asyncio.gather(*running)


def vehicle_client(base: str) -> httpx.AsyncClient:
    """A vehicle's own HTTP client: ``MAX_IN_FLIGHT`` connections to the server at ``base``."""
    return httpx.AsyncClient(base_url=base, timeout=120.0, limits=httpx.Limits(max_connections=MAX_IN_FLIGHT))


async def drive_vehicle(
    base: str,
    admin: dict[str, str],
    k: int,
    frames: list[tuple[float, bytes]],
    args: argparse.Namespace,
) -> tuple[list[float], list[str], bool, int]:
    """Replay frames as vehicle ``k`` (:func:`stream_frames`); returns latencies, answers, history check,
    frames due."""
    async with vehicle_client(base) as client:
        vehicle_id, headers = await add_vehicle(client, admin, f"v{k}", args.camera)
        latencies: list[float] = []
        statuses: list[str] = []

        def answered(_t_s: float, status: str, latency_ms: float | None) -> None:
            statuses.append(status)
            if latency_ms is not None:
                latencies.append(latency_ms)

        n = int(args.seconds * args.fps)
        await stream_frames(
            client, vehicle_id, headers, frames, k, n, args.fps, time.perf_counter() + 0.2, answered
        )
        await asyncio.sleep(0.5)  # let the lane store its last counts
        history = (await client.get(f"/api/vehicles/{vehicle_id}/positions", headers=admin)).json()
        state = (await client.get(f"/api/vehicles/{vehicle_id}/live-state", headers=admin)).json()
    ts = [p["t"] for p in history]
    sent = n - statuses.count("not sent")
    accounted = state["processed"] + state["skipped"] + state["out_of_order"] == sent
    in_order = all(a < b for a, b in itertools.pairwise(ts)) and len(ts) == state["processed"]
    return latencies, statuses, accounted and in_order, n


async def load(base: str, frames: list[tuple[float, bytes]], args: argparse.Namespace) -> None:
    admin = await log_in(base)
    results = await asyncio.gather(
        *(drive_vehicle(base, admin, k, frames, args) for k in range(args.vehicles))
    )
    latencies = np.array([x for r in results for x in r[0]])
    statuses = Counter(s for r in results for s in r[1])
    p50, p99 = float(np.median(latencies)), float(np.percentile(latencies, 99))
    print(
        f"{args.vehicles} vehicles x {args.fps:g} frames/s x {args.seconds:g} s = {sum(r[3] for r in results)} frames"
    )
    print(f"frame endpoint latency: p50 {p50:.1f} ms, p99 {p99:.1f} ms (target p99 <= {TARGET_P99_MS:g} ms)")
    print("answers: " + ", ".join(f"{k} {v}" for k, v in sorted(statuses.items())))
    shares = [r[1].count("processed") / r[3] for r in results]
    print(
        "processed per vehicle: "
        + ", ".join(f"v{k} {share:.0%}" for k, share in enumerate(shares))
        + f" (min/max {min(shares) / max(shares):.2f})"
    )
    ok = all(r[2] for r in results)
    print(f"lost, reordered or double-processed frames: {'0' if ok else 'SOME (check failed)'}")
    args.p50 = p50


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vehicles", type=int, default=5)
    parser.add_argument("--fps", type=float, default=10.0)
    parser.add_argument("--seconds", type=float, default=20.0)
    parser.add_argument("--size", default="tiny", choices=["tiny", "small"])
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="driftmap-bench-live-") as tmp:
        t0 = time.perf_counter()
        data, frames, args.camera = prepare(Path(tmp), args.size)
        print(f"{args.size} site simulated, imported and mapped in {time.perf_counter() - t0:.0f} s")
        base_ms = baseline_ms(data, frames, 100, args.camera)
        with serving(data, Path(tmp), "--no-worker") as (base, _pid):
            asyncio.run(load(base, frames, args))
        print(f"baseline (in-process decode + step + store, one vehicle): {base_ms:.1f} ms/frame")
        print(f"ratio HTTP p50 / baseline: {args.p50 / base_ms:.2f}")


if __name__ == "__main__":
    main()
