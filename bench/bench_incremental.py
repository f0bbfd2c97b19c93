"""Benchmark of an incremental map build: a site mapped, one mapping drive added, the map built again.

Imports a simulated site's mapping drives but the last into a fresh SQLite store and builds its map (what
``driftmap map build`` does: :func:`driftmap.services.maps.build_site_map`, stage 1 in ``--workers``
processes), which keeps every drive segment's odometry piece, its loop-closure search and its database's pair
scores. Then it imports the last mapping drive and builds three times on the same data: incrementally (the
kept pieces loaded, only the new drive's segments prepared, only its keyframes' loop-closure queries scored,
only database pairs not seen before scored, the pose graph started from the first version's poses),
incrementally with a cold pose graph, and in full (``--full``: every segment prepared again, the search
planned afresh, every database pair scored, cold pose graph). It prints each build's wall time and stages,
the ratio full / incremental, the pose graph's time cold / warm, what each build reused, the incremental and
full maps' distance to the simulator's true positions of the frames, and the distance between an incremental
build's pose of a frame and the full build's (largest, 99th percentile, mean; target: 0.1 m).

Sites are simulated into ``bench/out/site-SIZE-SEED`` the first time (bench_mapping.py's ``site_dir``).

Usage: ``PYTHONPATH=backend .venv/bin/python bench/bench_incremental.py [--size small] [--seed 7]
[--preset paper|fast] [--workers 2]``
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from sqlalchemy import select

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' helpers

from tests.sim_site import create_site, import_folders, version_poses

from bench_mapping import PRESETS, mapping_folders, mapping_truth, site_dir
from driftmap.config import Settings
from driftmap.core.mapping.pipeline import MappingParams
from driftmap.services import map_pieces
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.store.models import MapVersion
from driftmap.store.storage import Storage

TOLERANCE_M = 0.1  # the target: every pose of an incremental build within this of a full one's
STAGES = ("odometry_s", "frame_stats_s", "loop_closure_s", "pose_graph_s", "topomap_s")


def _import(storage: Storage, site: Path, folders: list[Path], create: bool) -> None:
    if create:
        create_site(storage, site, "bench")
    import_folders(storage, "bench", folders)


def _build(
    storage: Storage, params: MappingParams, workers: int, full: bool, warm: bool = True
) -> tuple[int, float, dict]:
    """One build of the site as the CLI runs it; (version, wall seconds, its stats)."""
    start = time.perf_counter()
    stale: set[str] = set()
    with storage.blobs.batch() as batch, storage.db.session() as session:
        record = site_service.get_site(session, "bench")
        version, build = map_service.build_site_map(
            session,
            storage.blobs,
            batch,
            record,
            params,
            workers=workers,
            full=full,
            warm_start=warm,
            stale=stale,
        )
        number = version.version
    map_pieces.drop_stale(storage, stale)
    return number, time.perf_counter() - start, dict(build.stats)


def _poses(storage: Storage, number: int) -> np.ndarray:
    with storage.db.session() as session:
        version_id = session.scalars(select(MapVersion.id).where(MapVersion.version == number)).one()
    return version_poses(storage, version_id)


def _line(name: str, seconds: float, stats: dict) -> str:
    stages = ", ".join(f"{k[:-2].replace('_', ' ')} {float(stats.get(k, 0.0)):.1f}" for k in STAGES)
    rest = seconds - sum(float(stats.get(k, 0.0)) for k in STAGES)
    reused = f"{stats['segments_reused']} of {stats['segments_reused'] + stats['segments_prepared']}"
    queries = (
        f"{stats['loop_queries_reused']} of {stats['loop_queries_reused'] + stats['loop_queries_scored']}"
    )
    graph = f"{stats['graph_warm_drives']} drives warm, {stats['graph_iterations']} final solve iterations"
    pairs = stats.get("database_pairs_reused", 0), stats.get("database_pairs_scored", 0)
    return (
        f"{name:<18}{seconds:6.1f} s ({stages}, other {rest:.1f}); segments reused {reused}; "
        f"loop-closure queries reused {queries}; database pairs reused {pairs[0]} of {sum(pairs)}; "
        f"graph {graph}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--size", default="small")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--preset", choices=sorted(PRESETS), default="paper")
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    site = site_dir(args.size, args.seed)
    params = PRESETS[args.preset]
    folders = mapping_folders(site)
    with tempfile.TemporaryDirectory(prefix="bench-incremental-") as tmp:
        storage = Storage.open(Settings(data_dir=Path(tmp)))
        try:
            _import(storage, site, folders[:-1], create=True)
            _v, first_s, first = _build(storage, params, args.workers, full=False)
            _import(storage, site, folders[-1:], create=False)
            incremental_v, incremental_s, incremental = _build(storage, params, args.workers, full=False)
            cold_v, cold_s, cold = _build(storage, params, args.workers, full=False, warm=False)
            full_v, full_s, full = _build(storage, params, args.workers, full=True)
            rebuilt = _poses(storage, full_v)[:, :2]
            grown = _poses(storage, incremental_v)[:, :2]
            gap = np.linalg.norm(grown - rebuilt, axis=1)
            cold_gap = np.linalg.norm(_poses(storage, cold_v)[:, :2] - rebuilt, axis=1)
        finally:
            storage.close()
    print(
        f"{args.size} site (seed {args.seed}), preset {args.preset}, {args.workers} workers: "
        f"{len(folders)} mapping drives, {full['frames']} frames; the last drive "
        f"({full['frames'] - first['frames']} frames) added"
    )
    print(_line("first", first_s, first))
    print(_line("incremental", incremental_s, incremental))
    print(_line("incremental, cold", cold_s, cold))
    print(_line("full", full_s, full))
    print(f"full / incremental: {full_s / incremental_s:.2f}x")
    warm_s, cold_graph_s = float(incremental["pose_graph_s"]), float(cold["pose_graph_s"])
    print(
        f"pose graph, cold / warm start: {cold_graph_s:.2f} s / {warm_s:.2f} s = {cold_graph_s / warm_s:.2f}x"
    )
    truth = np.concatenate(mapping_truth(site))
    for name, poses in (("incremental", grown), ("full", rebuilt)):
        error = np.linalg.norm(poses - truth, axis=1)
        print(
            f"{name} vs truth: mean {error.mean():.2f} m, median {np.median(error):.2f} m, "
            f"max {error.max():.1f} m"
        )
    for name, g in (("incremental", gap), ("incremental, cold", cold_gap)):
        verdict = "within" if g.max() <= TOLERANCE_M else "NOT within"
        print(
            f"{name} vs full poses: max {g.max():.2e} m, 99th percentile {np.percentile(g, 99):.2e} m, "
            f"mean {g.mean():.2e} m over {g.size} frames, {np.count_nonzero(g > TOLERANCE_M)} beyond "
            f"{TOLERANCE_M} m ({verdict})"
        )


if __name__ == "__main__":
    main()
