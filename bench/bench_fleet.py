"""Live localisation at fleet scale: up to 50 vehicles against PostgreSQL, Redis and two API processes.

The scale-out topology of ``docker-compose.yml`` on this machine: a private PostgreSQL and redis-server on
loopback, the tiny simulated site imported and mapped into the database, and ``driftmap serve --workers 2``
(two API processes sharing the Redis live hub, each with its localiser processes). For each fleet size in
``--fleets`` the vehicles stream the site's localisation drive for ``--seconds`` at ``--fps`` (open loop, as
``bench_live.py``), and the benchmark prints the frames offered and processed per second, the share processed
per vehicle (min/max: fair scheduling), the frame endpoint's p50/p99 latency, the CPU seconds per processed
frame of the server's processes and of PostgreSQL, and whether any processed frame is missing from the stored
history. Frames a machine cannot keep up with are answered ``skipped`` (the newest frame of a vehicle wins),
so saturation shows as a falling processed share, not as errors; a vehicle keeps at most 8 frames waiting for
an answer and drops new ones meanwhile (``not sent``).

The baseline is the same frames localised in this process without HTTP (decode + odometry + localiser step +
database write on the same PostgreSQL), one vehicle: the machine's capacity is about cores / that cost, and the
ratio of the server's CPU per frame to it is what serving costs on top.

Usage: ``.venv/bin/python bench/bench_fleet.py [--fleets 5,10,20,50] [--fps 10] [--seconds 20]``
"""

from __future__ import annotations

import argparse
import asyncio
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' PostgreSQL and Redis servers

from tests.postgres_server import PostgresServer, postgres_bin_dir
from tests.redis_server import running_redis

from bench_live import baseline_ms, drive_vehicle, log_in, prepare, serving
from proc_tree import tree_cpu_s

API_PROCESSES = 2


async def fleet(
    base: str, frames: list[tuple[float, bytes]], vehicles: int, first: int, args: argparse.Namespace
) -> dict[str, float]:
    """Stream ``vehicles`` vehicles (numbered from ``first``) at once; their figures."""
    admin = await log_in(base)
    results = await asyncio.gather(
        *(drive_vehicle(base, admin, first + k, frames, args) for k in range(vehicles))
    )
    latencies = np.array([x for r in results for x in r[0]])
    shares = [r[1].count("processed") / r[3] for r in results]
    processed = sum(r[1].count("processed") for r in results)
    return {
        "offered": sum(r[3] for r in results),
        "processed": processed,
        "fairness": min(shares) / max(shares) if max(shares) > 0 else 0.0,
        "p50": float(np.median(latencies)),
        "p99": float(np.percentile(latencies, 99)),
        "not_sent": sum(r[1].count("not sent") for r in results),
        "errors": sum(1 for r in results for s in r[1] if s.isdigit() and int(s) >= 500),
        "history_ok": float(all(r[2] for r in results)),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fleets", default="5,10,20,50", help="fleet sizes, run one after another")
    parser.add_argument("--fps", type=float, default=10.0)
    parser.add_argument("--seconds", type=float, default=20.0)
    args = parser.parse_args()
    bin_dir = postgres_bin_dir()
    if bin_dir is None:
        sys.exit("PostgreSQL is not installed (make system-packages)")
    with tempfile.TemporaryDirectory(prefix="driftmap-bench-fleet-") as tmp:
        work = Path(tmp)
        postgres = PostgresServer(bin_dir)
        postgres.start()
        try:
            with running_redis(work) as redis_url:
                url = postgres.create_database("fleet")
                t0 = time.perf_counter()
                data, frames, args.camera = prepare(work, "tiny", database_url=url)
                print(
                    f"tiny site simulated, imported and mapped into PostgreSQL in {time.perf_counter() - t0:.0f} s"
                )
                base_ms = baseline_ms(data, frames, 100, args.camera, database_url=url)
                env = {"DRIFTMAP_DATABASE_URL": url, "DRIFTMAP_REDIS_URL": redis_url}
                options = ("--no-worker", "--workers", str(API_PROCESSES))
                with serving(data, work, *options, env=env) as (base, pid):
                    run(base, pid, postgres.pid or 0, frames, base_ms, args)
        finally:
            postgres.stop()


def run(
    base: str,
    pid: int,
    pg_pid: int,
    frames: list[tuple[float, bytes]],
    base_ms: float,
    args: argparse.Namespace,
) -> None:
    print(
        f"{API_PROCESSES} API processes, PostgreSQL + Redis, {os.cpu_count()} cores; "
        f"{args.fps:g} frames/s per vehicle for {args.seconds:g} s"
    )
    print(
        f"{'vehicles':>8} {'offered/s':>9} {'not sent':>8} {'processed/s':>11} {'share':>6} {'fair':>5} {'p50 ms':>7} "
        f"{'p99 ms':>7} {'server CPU ms/frame':>19} {'x baseline':>10} {'PostgreSQL':>10} {'5xx':>4} {'history':>7}"
    )
    first = 0
    for vehicles in (int(v) for v in args.fleets.split(",")):
        cpu0, pg0 = tree_cpu_s(pid), tree_cpu_s(pg_pid)
        figures = asyncio.run(fleet(base, frames, vehicles, first, args))
        cpu1, pg1 = tree_cpu_s(pid), tree_cpu_s(pg_pid)
        first += vehicles
        done = max(figures["processed"], 1.0)
        print(
            f"{vehicles:>8} {figures['offered'] / args.seconds:>9.0f} {figures['not_sent'] / figures['offered']:>8.0%} "
            f"{figures['processed'] / args.seconds:>11.1f} "
            f"{figures['processed'] / figures['offered']:>6.0%} {figures['fairness']:>5.2f} {figures['p50']:>7.1f} "
            f"{figures['p99']:>7.1f} {(cpu1 - cpu0) / done * 1e3:>19.1f} {(cpu1 - cpu0) / done * 1e3 / base_ms:>10.2f} "
            f"{(pg1 - pg0) / done * 1e3:>10.1f} "
            f"{figures['errors']:>4.0f} {'ok' if figures['history_ok'] else 'LOST':>7}"
        )
    print(
        f"baseline (in-process decode + odometry + step + store, one vehicle): {base_ms:.1f} ms/frame, "
        f"so {os.cpu_count()} cores hold about {(os.cpu_count() or 1) * 1e3 / base_ms:.0f} frames/s"
    )


if __name__ == "__main__":
    main()
