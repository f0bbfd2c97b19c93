"""Soak benchmark of the live path: vehicles stream frames to a real ``driftmap serve`` for half an hour.

Simulates, imports and maps the tiny site as ``bench_live.py`` does, then starts ``driftmap serve`` (with its
supervised job worker, as installed) and runs, for ``--minutes``: ``--vehicles`` vehicles each posting one frame
every 1/``--fps`` s (open loop, the site's localisation drive replayed in a loop with a clock that keeps
running), two control-room watchers on ``/api/live``, and every 30 s a one-minute history query and the latest
positions, as a control-room screen asks. Every 15 s it samples the resident memory (RSS, from ``/proc``) of the
server and each of its descendant processes (localiser processes, the job worker).

Prints the memory at the end of the warm-up (``--warmup`` minutes: maps loaded, caches filled) and at the end
(medians of the samples in the minute before each), the growth between them per process and in all, and the
acknowledged positions lost: a frame answered ``processed`` whose position is not in the stored history, and
the answers by kind (``not sent``: dropped by the vehicle while 8 frames waited for an answer).
The baseline is the warm-up's own memory. Target (issue 25): growth under 5 %, 0 lost positions.
``--plot FILE`` draws the memory over time (docs/evaluation/soak_live.png).

Usage: ``.venv/bin/python bench/soak_live.py [--minutes 30] [--vehicles 5] [--fps 10] [--plot FILE]``
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import statistics
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

import httpx
import websockets

from bench_live import (  # bench/ is the script's folder, first on sys.path
    add_vehicle,
    prepare,
    serving,
    stream_frames,
    vehicle_client,
)
from proc_tree import tree_rss_mb

SAMPLE_EVERY_S = 15.0
QUERY_EVERY_S = 30.0
TARGET_GROWTH = 0.05


@dataclass
class Soak:
    """What the run saw; ``samples`` are (minutes since start, RSS MB per role)."""

    samples: list[tuple[float, dict[str, float]]] = field(default_factory=list)
    statuses: Counter[str] = field(default_factory=Counter)
    latencies_ms: list[float] = field(default_factory=list)
    live_messages: int = 0
    queries: int = 0
    query_errors: int = 0


async def vehicle(
    base: str,
    admin: dict[str, str],
    k: int,
    frames: list[tuple[float, bytes]],
    args: argparse.Namespace,
    soak: Soak,
) -> tuple[int, set[float]]:
    """Stream frames as vehicle ``k`` until the run ends (:func:`bench_live.stream_frames`); returns its id
    and the ``t`` answered processed."""
    async with vehicle_client(base) as client:
        vehicle_id, headers = await add_vehicle(client, admin, f"soak-{k}", args.camera)
        processed: set[float] = set()

        def answered(t_s: float, status: str, latency_ms: float | None) -> None:
            soak.statuses[status] += 1
            if latency_ms is not None:
                soak.latencies_ms.append(latency_ms)
            if status == "processed":
                processed.add(t_s)

        n = int(args.minutes * 60 * args.fps)
        start = time.perf_counter() + 0.1 * k / args.vehicles
        await stream_frames(client, vehicle_id, headers, frames, k, n, args.fps, start, answered)
    return vehicle_id, processed


async def watcher(base: str, token: str, stop: asyncio.Event, soak: Soak) -> None:
    """A control-room screen on ``/api/live``: counts the messages it is pushed."""
    url = base.replace("http://", "ws://") + "/api/live"
    async with websockets.connect(url, additional_headers={"Authorization": f"Bearer {token}"}) as socket:
        while not stop.is_set():
            try:
                await asyncio.wait_for(socket.recv(), 1.0)
                soak.live_messages += 1
            except TimeoutError:
                continue


async def control_room(
    client: httpx.AsyncClient, admin: dict[str, str], stop: asyncio.Event, soak: Soak
) -> None:
    """Every 30 s: the last minute of one vehicle's history and every vehicle's latest position."""
    while not stop.is_set():
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(stop.wait(), QUERY_EVERY_S)
        latest = await client.get("/api/positions/latest", headers=admin)
        rows = latest.json() if latest.status_code == 200 else []
        soak.queries += 1
        soak.query_errors += latest.status_code != 200
        placed = [r for r in rows if r["position"] is not None]
        if placed:
            row = placed[0]
            t = float(row["position"]["t"])
            history = await client.get(
                f"/api/vehicles/{row['vehicle_id']}/positions",
                params={"start": max(t - 60.0, 0.0)},
                headers=admin,
            )
            soak.queries += 1
            soak.query_errors += history.status_code != 200


async def sampler(pid: int, started: float, stop: asyncio.Event, soak: Soak) -> None:
    while not stop.is_set():
        soak.samples.append(((time.perf_counter() - started) / 60.0, tree_rss_mb(pid)))
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(stop.wait(), SAMPLE_EVERY_S)


async def run(base: str, pid: int, frames: list[tuple[float, bytes]], args: argparse.Namespace) -> Soak:
    soak, stop = Soak(), asyncio.Event()
    async with httpx.AsyncClient(
        base_url=base, timeout=120.0, limits=httpx.Limits(max_connections=200)
    ) as client:
        login = await client.post("/api/auth/login", json={"username": "bench", "password": "bench-password"})
        token = login.json()["access_token"]
        admin = {"Authorization": f"Bearer {token}"}
        started = time.perf_counter()
        side = [
            asyncio.create_task(sampler(pid, started, stop, soak)),
            asyncio.create_task(control_room(client, admin, stop, soak)),
            *(asyncio.create_task(watcher(base, token, stop, soak)) for _ in range(2)),
        ]
        fleet = await asyncio.gather(
            *(vehicle(base, admin, k, frames, args, soak) for k in range(args.vehicles))
        )
        stop.set()
        await asyncio.gather(*side)
        soak.samples.append(((time.perf_counter() - started) / 60.0, tree_rss_mb(pid)))
        await asyncio.sleep(1.0)  # the lanes store their last positions
        lost = 0
        for vehicle_id, processed in fleet:
            answer = await client.get(
                f"/api/vehicles/{vehicle_id}/positions", params={"limit": 100000}, headers=admin
            )
            stored = {round(float(p["t"]), 3) for p in answer.json()}
            lost += len(processed - stored)
        args.lost, args.acknowledged = lost, sum(len(p) for _v, p in fleet)
    return soak


def _window(soak: Soak, end_min: float) -> dict[str, float]:
    """Median RSS per role (and ``all``) of the samples in the minute before ``end_min``."""
    rows = [s for m, s in soak.samples if end_min - 1.0 <= m <= end_min] or [soak.samples[-1][1]]
    roles = sorted({r for s in rows for r in s})
    out = {r: statistics.median(s.get(r, 0.0) for s in rows) for r in roles}
    out["all"] = statistics.median(sum(s.values()) for s in rows)
    return out


def report(soak: Soak, args: argparse.Namespace) -> None:
    end = soak.samples[-1][0]
    warm, last = _window(soak, args.warmup), _window(soak, end)
    print(
        f"{args.vehicles} vehicles x {args.fps:g} frames/s x {args.minutes:g} min; 2 live watchers; "
        f"{soak.queries} control-room queries ({soak.query_errors} not 200)"
    )
    print("answers: " + ", ".join(f"{k} {v}" for k, v in sorted(soak.statuses.items())))
    lat = sorted(soak.latencies_ms)
    print(
        f"frame endpoint latency: p50 {lat[len(lat) // 2]:.1f} ms, p99 {lat[int(len(lat) * 0.99)]:.1f} ms; "
        f"live messages pushed to the watchers: {soak.live_messages}"
    )
    print(
        f"resident memory, MB (median of the minute before): at {args.warmup:g} min (baseline) -> at {end:.1f} min"
    )
    for role in warm:
        growth = last.get(role, 0.0) / warm[role] - 1.0 if warm[role] else 0.0
        print(f"  {role:20s} {warm[role]:8.1f} -> {last.get(role, 0.0):8.1f}  ({growth:+.1%})")
    growth = last["all"] / warm["all"] - 1.0
    print(f"growth of all: {growth:+.1%} (target < {TARGET_GROWTH:.0%})")
    print(f"positions acknowledged {args.acknowledged}, lost {args.lost} (target 0)")


def plot(soak: Soak, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    roles = sorted({r for _m, s in soak.samples for r in s})
    minutes = [m for m, _s in soak.samples]
    fig, ax = plt.subplots(figsize=(7, 3.5))
    for role in roles:
        ax.plot(minutes, [s.get(role, 0.0) for _m, s in soak.samples], label=role)
    ax.plot(minutes, [sum(s.values()) for _m, s in soak.samples], label="all", color="black")
    ax.set_xlabel("minutes")
    ax.set_ylabel("resident memory, MB")
    ax.set_ylim(bottom=0)
    ax.legend(loc="lower right")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"memory over time: {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0)
    parser.add_argument("--warmup", type=float, default=5.0, help="minutes before the baseline memory")
    parser.add_argument("--vehicles", type=int, default=5)
    parser.add_argument("--fps", type=float, default=10.0)
    parser.add_argument("--plot", type=Path)
    parser.add_argument("--samples", type=Path, help="write the memory samples here (JSON)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="driftmap-soak-") as tmp:
        t0 = time.perf_counter()
        data, frames, args.camera = prepare(Path(tmp), "tiny")
        print(f"tiny site simulated, imported and mapped in {time.perf_counter() - t0:.0f} s")
        with serving(data, Path(tmp)) as (base, pid):
            soak = asyncio.run(run(base, pid, frames, args))
    report(soak, args)
    if args.samples:
        args.samples.write_text(json.dumps(soak.samples))
    if args.plot:
        plot(soak, args.plot)


if __name__ == "__main__":
    main()
