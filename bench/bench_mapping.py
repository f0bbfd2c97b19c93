"""Benchmark of the whole mapping pipeline (driftmap.core.mapping.pipeline.build_map) on simulated sites.

Maps the mapping drives of a simulated site end to end -- visual odometry of every frame, keyframes,
loop-closure search, pose graph with groundings, topological map -- exactly as ``driftmap map build``
does, but reading the drive folders directly (no database). Prints the seconds and frames per second of
each stage and the total against the issue's 3-minute target for the medium site. The drives' odometry
(stage 1, the bulk of the time) runs in ``--workers`` spawned processes, each given a drive segment
(``--threads`` runs it in threads of this process instead: Python-bound, about one core); the pieces are
joined exactly as the map.build job joins its map.drive subtasks. Then it runs the odometry stage again on
one thread, the baseline, and prints the ratio.

Then it shows how the loop-closure search grows with the site: on the keyframes (one per metre of true
travel) of each size's mapping drives it times ``detect_loops`` and prints the full shifted-SAD
comparisons against the N^2/2 of the paper's all-pairs search.

Sites are simulated into ``bench/out/site-SIZE-SEED`` the first time (medium takes a few minutes; large
about twenty, so large is measured only when asked for with ``--growth small medium large``).

Usage: ``.venv/bin/python bench/bench_mapping.py [--size medium] [--seed 7] [--preset paper|fast]
[--workers 2] [--threads] [--growth small medium] [--no-baseline]``
"""

from __future__ import annotations

import argparse
import multiprocessing
import statistics
import time
from collections.abc import Iterator
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from bench_loops import load_site
from driftmap.core.loop_closure.params import LOOPS_DEFAULT
from driftmap.core.loop_closure.search import detect_loops
from driftmap.core.mapping.drive import PreparedSegment
from driftmap.core.mapping.pipeline import (
    MAPPING_FAST,
    MAPPING_PAPER,
    MapBuild,
    MappingDrive,
    MappingParams,
    build_map,
    build_segments,
    flat_offsets,
    join_drives,
    join_segments,
    prepare_drives,
    prepare_segment,
    solve_map,
    variant,
)
from driftmap.formats.drive_folder import DriveFolder, read_drive_folder
from driftmap.formats.frame_images import decode_gray
from driftmap.services.map_drives import single_threaded_worker
from driftmap.sim import simulate_site

OUT = Path(__file__).resolve().parent / "out"
TARGET_S = 180.0  # the target for the medium site
PRESETS = {"paper": MAPPING_PAPER, "fast": MAPPING_FAST}


def site_dir(size: str, seed: int) -> Path:
    """The simulated site of this size and seed, simulated on first use."""
    folder = OUT / f"site-{size}-{seed}"
    if not (folder / "site.json").exists():
        print(f"simulating the {size} site (seed {seed}) into {folder} ...", flush=True)
        if folder.exists():
            for path in sorted(folder.rglob("*"), reverse=True):
                path.unlink() if path.is_file() else path.rmdir()
        simulate_site(folder, seed=seed, size=size, obscurants=False)
    return folder


def _frames(folder: DriveFolder, begin: int = 0, stop: int | None = None) -> Iterator[np.ndarray]:
    for path in folder.frame_files[begin:stop]:
        yield decode_gray(path.read_bytes())


def mapping_folders(site: Path) -> list[Path]:
    """The site's mapping drive folders, in build order."""
    return [p for p in sorted((site / "drives").iterdir()) if read_drive_folder(p).meta.kind == "mapping"]


def mapping_truth(site: Path) -> list[np.ndarray]:
    """Per mapping drive (in :func:`mapping_folders` order), (N, 2) true floor positions of its frames, m."""
    return [
        np.array([(row.x_m, row.y_m) for row in read_drive_folder(path).frames], dtype=np.float64)
        for path in mapping_folders(site)
    ]


def folder_drive(path: Path) -> MappingDrive:
    """One drive folder as the pipeline takes it (frames decoded lazily from disk)."""
    folder = read_drive_folder(path)
    index = {row.frame: k for k, row in enumerate(folder.frames)}
    return MappingDrive(
        name=folder.meta.name,
        camera=folder.meta.camera,
        t_s=np.array([row.t_s for row in folder.frames], dtype=np.float64),
        frames=lambda f=folder: _frames(f),  # type: ignore[misc]
        groundings=[(index[g.frame], g.x_m, g.y_m) for g in folder.groundings],
        frame_range=lambda begin, stop, f=folder: _frames(f, begin, stop),  # type: ignore[misc]
    )


def mapping_drives(site: Path) -> list[MappingDrive]:
    """The site's mapping drives as the pipeline takes them (frames decoded lazily from disk)."""
    return [folder_drive(p) for p in mapping_folders(site)]


def _prepare_folder(
    path: Path, params: MappingParams, flat: tuple[int, int], span: tuple[int, int]
) -> dict[str, np.ndarray]:
    """Stage 1 of one segment of a drive folder, in a worker process; its piece as arrays."""
    return prepare_segment(folder_drive(path), params, flat, span).to_arrays()


def build_in_processes(site: Path, params: MappingParams, workers: int) -> MapBuild:
    """The build as ``driftmap map build --workers`` runs it: every drive segment's stage 1 in one of
    ``workers`` spawned processes (one OpenCV thread each), joined per drive here, then the loop-closure
    search, pose graph and topological map in this process."""
    paths = mapping_folders(site)
    drives = [folder_drive(p) for p in paths]
    flats = flat_offsets(drives)
    segments = build_segments(drives, params)
    start = time.perf_counter()
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(
        min(workers, len(segments)), mp_context=context, initializer=single_threaded_worker
    ) as pool:
        futures = [pool.submit(_prepare_folder, paths[k], params, flats[k], span) for k, span in segments]
        done = [
            PreparedSegment.from_arrays(
                fut.result(), params.database, params.images, flats[k][0] + span[0], flats[k][1]
            )
            for fut, (k, span) in zip(futures, segments, strict=True)
        ]
    pieces = [
        join_segments(d, [s for (j, _span), s in zip(segments, done, strict=True) if j == k], params)
        for k, d in enumerate(drives)
    ]
    prepared = join_drives(pieces, drives, params, None, time.perf_counter() - start)
    return solve_map(prepared, drives, params)


def bench_build(site: Path, preset: str, workers: int, threads: bool, baseline: bool) -> None:
    drives = mapping_drives(site)
    params = PRESETS[preset]
    n = sum(len(d.t_s) for d in drives)
    how = "threads" if threads else "processes"
    print(
        f"\n{site.name}: {len(drives)} mapping drives, {n:,} frames, preset {preset}, {workers} worker {how}"
    )
    start = time.perf_counter()
    if threads:
        build = build_map(drives, params, workers=workers)
    else:
        build = build_in_processes(site, params, workers)
    total = time.perf_counter() - start
    st = build.stats
    print(f"{'stage':<18}{'s':>9}{'frames/s':>11}")
    for stage in ("odometry", "loop_closure", "pose_graph", "topomap"):
        seconds = float(st.get(f"{stage}_s", float("nan")))
        print(f"{stage:<18}{seconds:>9.1f}{n / max(seconds, 1e-9):>11.0f}")
    verdict = "meets" if total <= TARGET_S else "misses"
    print(f"{'total':<18}{total:>9.1f}{n / total:>11.0f}   ({verdict} the {TARGET_S:.0f} s target)")
    print(
        f"keyframes {st['keyframes']:,}, closures {st['closures_accepted']}/{st['closures_found']} accepted, "
        f"{st['groundings']} groundings, {st['nodes']:,} nodes"
    )
    if baseline and workers > 1:
        t0 = time.perf_counter()
        prepare_drives(drives, variant(params, loops=False, groundings=True), workers=1)
        single = time.perf_counter() - t0
        parallel = float(st["odometry_s"])
        print(
            f"baseline odometry on 1 thread: {single:.1f} s -> {single / parallel:.2f}x with {workers} {how}"
        )


def bench_growth(sizes: list[str], seed: int, runs: int) -> None:
    print("\nloop-closure search growth (keyframes every 1 m of true travel, mapping drives)")
    header = f"{'size':<8}{'keyframes':>10}{'full SAD':>11}{'of N^2/2':>10}{'closures':>9}{'median s':>10}"
    print(header)
    print("-" * len(header))
    for size in sizes:
        chains, _poses, times = load_site(site_dir(size, seed), 1.0, localisation=False)
        n = sum(len(c) for c in chains)
        seconds = []
        for _ in range(runs):
            t0 = time.perf_counter()
            result = detect_loops(chains, LOOPS_DEFAULT, times)
            seconds.append(time.perf_counter() - t0)
        share = result.stats.n_full / (n * n / 2)
        print(
            f"{size:<8}{n:>10,}{result.stats.n_full:>11,}{share:>10.2%}{len(result.closures):>9}"
            f"{statistics.median(seconds):>10.2f}"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", default="medium", choices=["tiny", "small", "medium", "large"])
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--site", type=Path, help="a simulated site folder instead of --size/--seed")
    parser.add_argument("--preset", default="paper", choices=sorted(PRESETS))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--threads", action="store_true", help="odometry in threads, not processes")
    parser.add_argument("--growth", nargs="*", default=["small", "medium"])
    parser.add_argument("--runs", type=int, default=3, help="runs of each loop search (median)")
    parser.add_argument("--no-baseline", action="store_true", help="skip the one-thread odometry baseline")
    args = parser.parse_args()
    site = args.site or site_dir(args.size, args.seed)
    bench_build(site, args.preset, args.workers, args.threads, not args.no_baseline)
    if args.growth:
        bench_growth(args.growth, args.seed, args.runs)


if __name__ == "__main__":
    main()
