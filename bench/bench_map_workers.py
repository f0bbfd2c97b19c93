"""Benchmark of the fanned-out map build: one ``map.build`` job through the real queue on 1, then 2 workers.

Imports a simulated site's mapping drives (survey and groundings included) into a fresh data dir, then for
each worker count starts that many real ``driftmap worker`` processes (one job thread each), waits until
they are up, submits a ``map.build`` job and times it from submission to ``succeeded``; the workers are
stopped after each build. The build's drives run as ``map.drive`` subtasks and its loop-closure search as
``map.loops`` subtasks (blocks of query keyframes) that any worker takes (driftmap.jobs.map_tasks), so the
second worker should cut the odometry stage, the bulk of a build, about in half on two cores; the pose graph
and topological map run once, on the parent's worker. Prints each build's wall time, its stage seconds, how
many drives and loop blocks each worker process ran (``drives+blocks`` per process), the medians
and the speed-up of 2 workers over 1, and checks that every build stored the same poses. The 1-minute load
average before and after each build is printed too: other jobs on the machine take cores from the workers.

Embedded SQLite + SqliteHuey by default; ``--database-url postgresql+psycopg://...`` and ``--redis-url
redis://...`` run it on PostgreSQL + Redis (the database must be empty or hold this bench's site).

Usage: ``.venv/bin/python bench/bench_map_workers.py [--site DIR | --size small --seed 7] [--preset paper]
[--workers 1 2] [--runs 1] [--data-dir DIR] [--database-url URL] [--redis-url URL]``
"""

from __future__ import annotations

import argparse
import hashlib
import os
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

from sqlalchemy import select

from driftmap.config import Settings
from driftmap.jobs.queue import JobQueue
from driftmap.services import drives as drive_service
from driftmap.services import jobs as job_service
from driftmap.services import sites as site_service
from driftmap.store.job_models import Job
from driftmap.store.models import MapPose, Site
from driftmap.store.storage import Storage

OUT = Path(__file__).resolve().parent / "out"
DRIFTMAP = Path(sys.executable).with_name("driftmap")
SITE = "bench-workers"
STAGES = ("odometry_s", "frame_stats_s", "loop_closure_s", "pose_graph_s", "topomap_s")


def site_dir(size: str, seed: int) -> Path:
    """The simulated site of this size and seed (bench/out/site-SIZE-SEED, simulated on first use)."""
    folder = OUT / f"site-{size}-{seed}"
    if not (folder / "site.json").exists():
        from driftmap.sim import simulate_site

        print(f"simulating the {size} site (seed {seed}) into {folder} ...", flush=True)
        shutil.rmtree(folder, ignore_errors=True)
        simulate_site(folder, seed=seed, size=size, obscurants=False)
    return folder


def import_mapping_drives(storage: Storage, site: Path) -> None:
    """Site :data:`SITE` from ``site``'s survey and mapping drives, unless it is there already."""
    with storage.db.session() as session:
        if session.scalar(select(Site.id).where(Site.name == SITE)) is not None:
            print(f"site {SITE!r} is already imported", flush=True)
            return
    start = time.perf_counter()
    with storage.blobs.batch() as batch, storage.db.session() as session:
        record = site_service.create_site(session, SITE)
        site_service.add_survey_map(session, batch, record, (site / "survey.dxf").read_bytes(), "survey.dxf")
    for folder in drive_service.drive_folders_in(site / "drives"):
        if not folder.name.startswith("map"):
            continue
        with storage.blobs.batch() as batch, storage.db.session() as session:
            drive_service.import_drive(session, batch, site_service.get_site(session, SITE), folder)
    print(f"imported {site} in {time.perf_counter() - start:.1f} s", flush=True)


def start_workers(n: int, env: dict[str, str], logs: Path) -> list[subprocess.Popen[bytes]]:
    """``n`` worker processes (``-v``: their start is logged), once each has logged that it consumes the queue."""
    procs, files = [], []
    for k in range(n):
        log = logs / f"worker-{n}-{k}.log"
        files.append(log)
        handle = log.open("wb")
        procs.append(
            subprocess.Popen(
                [str(DRIFTMAP), "-v", "worker"], env=env, stdout=handle, stderr=subprocess.STDOUT
            )
        )
    deadline = time.monotonic() + 120.0
    while not all("thread(s) on" in f.read_text(errors="replace") for f in files):
        for proc, f in zip(procs, files, strict=True):
            if proc.poll() is not None:
                raise SystemExit(f"worker exited:\n{f.read_text()}")
        if time.monotonic() > deadline:
            raise SystemExit("workers did not start within 120 s")
        time.sleep(0.2)
    return procs


def stop_workers(procs: list[subprocess.Popen[bytes]]) -> None:
    for proc in procs:
        proc.terminate()
    for proc in procs:
        try:
            proc.wait(60)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def one_build(storage: Storage, queue: JobQueue, preset: str) -> tuple[float, Job, list[Job]]:
    """Submit a map build, wait for it; (seconds from submission to the end, the job, its subtasks)."""
    with storage.db.session() as session:
        site_id = site_service.get_site(session, SITE).id
        job_id = job_service.submit(
            session, queue.enqueue, "map.build", {"preset": preset}, site_id=site_id, created_by="bench"
        ).id
    start = time.perf_counter()
    while True:
        with storage.db.session() as session:
            job = job_service.get_job(session, job_id)
            if job.status in job_service.FINAL_STATUSES:
                seconds = time.perf_counter() - start
                return seconds, job, job_service.children(session, job_id)
        time.sleep(0.2)


def poses_digest(storage: Storage, map_version_id: int) -> str:
    with storage.db.session() as session:
        rows = session.execute(
            select(MapPose.frame_id, MapPose.x_m, MapPose.y_m, MapPose.yaw_rad)
            .where(MapPose.map_version_id == map_version_id)
            .order_by(MapPose.frame_id)
        ).all()
    return hashlib.sha256(repr([tuple(r) for r in rows]).encode()).hexdigest()[:16]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--site", type=Path, help="a simulated site folder instead of --size/--seed")
    parser.add_argument("--size", default="small", choices=["tiny", "small", "medium", "large"])
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--preset", default="paper", choices=["paper", "fast"])
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="worker counts, in order")
    parser.add_argument("--runs", type=int, default=1, help="builds per worker count (median)")
    parser.add_argument("--data-dir", type=Path, help="data dir (default: a fresh one under bench/out)")
    parser.add_argument("--database-url", help="e.g. postgresql+psycopg://user@127.0.0.1:5432/db")
    parser.add_argument("--redis-url", help="e.g. redis://127.0.0.1:6379/0 (the queue; else SqliteHuey)")
    args = parser.parse_args()
    site = args.site or site_dir(args.size, args.seed)
    data_dir = args.data_dir or OUT / f"map-workers-{site.name}"
    if args.data_dir is None and args.database_url is None:
        shutil.rmtree(data_dir, ignore_errors=True)
    settings = Settings(data_dir=data_dir, database_url=args.database_url, redis_url=args.redis_url)
    env = {**os.environ, "DRIFTMAP_DATA_DIR": str(data_dir)}
    for key, value in (("DRIFTMAP_DATABASE_URL", args.database_url), ("DRIFTMAP_REDIS_URL", args.redis_url)):
        if value:
            env[key] = value
        else:
            env.pop(key, None)
    storage = Storage.open(settings)
    queue = JobQueue(settings)
    import_mapping_drives(storage, site)
    logs = data_dir / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    backend = (
        f"{'PostgreSQL' if args.database_url else 'SQLite'} + {'Redis' if args.redis_url else 'SqliteHuey'}"
    )
    print(f"\n{site.name}: map.build (preset {args.preset}) on {backend}, {os.cpu_count()} cores")
    header = f"{'workers':>7}{'run':>5}{'wall s':>9}" + "".join(f"{s[:-2]:>14}" for s in STAGES)
    print(header + "   drives+blocks per process   poses   load before/after")
    walls: dict[int, list[float]] = {}
    digests = set()
    for n in args.workers:
        for run in range(args.runs):
            procs = start_workers(n, env, logs)
            load_before = os.getloadavg()[0]
            try:
                seconds, job, subtasks = one_build(storage, queue, args.preset)
            finally:
                stop_workers(procs)
            if job.status != "succeeded" or job.result is None:
                raise SystemExit(f"build job {job.id} {job.status}: {job.error}")
            stats = job.result["stats"]
            per_process: dict[str, list[int]] = {}
            for sub in subtasks:
                key = ":".join((sub.worker_id or "?").split(":")[:2])
                counts = per_process.setdefault(key, [0, 0])
                counts[sub.kind == "map.loops"] += 1
            digest = poses_digest(storage, int(job.result["map_version_id"]))
            digests.add(digest)
            walls.setdefault(n, []).append(seconds)
            cells = "".join(f"{float(stats.get(s, float('nan'))):>14.1f}" for s in STAGES)
            spread = " ".join(f"{d}+{b}" for d, b in sorted(per_process.values(), reverse=True))
            load = f"{load_before:.1f}/{os.getloadavg()[0]:.1f}"
            print(f"{n:>7}{run + 1:>5}{seconds:>9.1f}{cells}   {spread:<27} {digest}   {load}", flush=True)
    print()
    for n, values in walls.items():
        print(f"{n} worker process(es): median {statistics.median(values):.1f} s over {len(values)} build(s)")
    if 1 in walls and 2 in walls:
        ratio = statistics.median(walls[1]) / statistics.median(walls[2])
        print(f"speed-up of 2 workers over 1: {ratio:.2f}x (a 2-core machine bounds it near 2x)")
    print("every build stored the same poses" if len(digests) == 1 else f"POSES DIFFER: {sorted(digests)}")
    queue.close()
    storage.close()


if __name__ == "__main__":
    main()
