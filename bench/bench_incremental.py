"""Benchmark of an incremental map build: a site mapped, one mapping drive added, the map built again.

Imports a simulated site's mapping drives but the last into a fresh SQLite store and builds its map (what
``driftmap map build`` does: :func:`driftmap.services.maps.build_site_map`, stage 1 in ``--workers``
processes), which keeps every drive segment's odometry piece, its loop-closure search and its database's pair
scores. Then it imports the last mapping drive and builds three times on the same data: incrementally (the
kept pieces loaded, only the new drive's segments prepared, only its keyframes' loop-closure queries scored,
only database pairs not seen before scored), again with nothing changed (everything kept: the cost of a build
after a grounding edit), and in full (``--full``: every segment prepared again, the search planned afresh,
every database pair scored). It prints each build's wall time and stages, the ratio full / incremental, what
each build reused, the incremental and full maps' distance to the simulator's true positions of the frames,
and the distance between an incremental build's pose of a frame and the full build's (largest, 99th
percentile, mean; target: 0.1 m).

Sites are simulated into ``bench/out/site-SIZE-SEED`` the first time (bench_mapping.py's ``site_dir``).
With ``--first-store DIR`` the store after the first build is kept in ``DIR`` (made the first time) and each
run starts from a copy of it: on the 20 km site that first build is half an hour.

Usage: ``PYTHONPATH=backend .venv/bin/python bench/bench_incremental.py [--size small] [--seed 7]
[--preset paper|fast] [--workers 2] [--first-store DIR]``
"""

from __future__ import annotations

import argparse
import json
import shutil
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


def _first_build(store: Path, site: Path, folders: list[Path], params: MappingParams, workers: int) -> dict:
    """Import ``folders`` into a fresh store in ``store`` and build its map, unless ``store`` holds that
    already; the build's stats with its wall time (``wall_s``)."""
    done = store / "first-build.json"
    if not done.exists():
        if store.exists():
            shutil.rmtree(store)
        storage = Storage.open(Settings(data_dir=store))
        try:
            _import(storage, site, folders, create=True)
            _v, seconds, stats = _build(storage, params, workers, full=False)
        finally:
            storage.close()
        done.write_text(json.dumps({**stats, "wall_s": seconds}))
    return dict(json.loads(done.read_text()))


def _build(storage: Storage, params: MappingParams, workers: int, full: bool) -> tuple[int, float, dict]:
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
    graph = f"{stats['graph_nodes']} nodes, {stats['graph_iterations']} final solve iterations"
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
    parser.add_argument("--first-store", type=Path, help="keep the store after the first build here")
    args = parser.parse_args()
    site = site_dir(args.size, args.seed)
    params = PRESETS[args.preset]
    folders = mapping_folders(site)
    with tempfile.TemporaryDirectory(prefix="bench-incremental-") as tmp:
        first_store = args.first_store or Path(tmp) / "first"
        first = _first_build(first_store, site, folders[:-1], params, args.workers)
        first_s = float(first["wall_s"])
        store = first_store
        if args.first_store is not None:  # kept: build on a copy
            store = Path(tmp) / "store"
            shutil.copytree(first_store, store, ignore=shutil.ignore_patterns("first-build.json"))
        storage = Storage.open(Settings(data_dir=store))
        try:
            _import(storage, site, folders[-1:], create=False)
            incremental_v, incremental_s, incremental = _build(storage, params, args.workers, full=False)
            again_v, again_s, again = _build(storage, params, args.workers, full=False)
            full_v, full_s, full = _build(storage, params, args.workers, full=True)
            rebuilt = _poses(storage, full_v)[:, :2]
            grown = _poses(storage, incremental_v)[:, :2]
            gap = np.linalg.norm(grown - rebuilt, axis=1)
            again_gap = np.linalg.norm(_poses(storage, again_v)[:, :2] - rebuilt, axis=1)
        finally:
            storage.close()
    print(
        f"{args.size} site (seed {args.seed}), preset {args.preset}, {args.workers} workers: "
        f"{len(folders)} mapping drives, {full['frames']} frames; the last drive "
        f"({full['frames'] - first['frames']} frames) added"
    )
    print(_line("first", first_s, first))
    print(_line("incremental", incremental_s, incremental))
    print(_line("nothing changed", again_s, again))
    print(_line("full", full_s, full))
    print(f"full / incremental: {full_s / incremental_s:.2f}x")
    truth = np.concatenate(mapping_truth(site))
    for name, poses in (("incremental", grown), ("full", rebuilt)):
        error = np.linalg.norm(poses - truth, axis=1)
        print(
            f"{name} vs truth: mean {error.mean():.2f} m, median {np.median(error):.2f} m, "
            f"max {error.max():.1f} m"
        )
    for name, g in (("incremental", gap), ("nothing changed", again_gap)):
        verdict = "within" if g.max() <= TOLERANCE_M else "NOT within"
        print(
            f"{name} vs full poses: max {g.max():.2e} m, 99th percentile {np.percentile(g, 99):.2e} m, "
            f"mean {g.mean():.2e} m over {g.size} frames, {np.count_nonzero(g > TOLERANCE_M)} beyond "
            f"{TOLERANCE_M} m ({verdict})"
        )


if __name__ == "__main__":
    main()
