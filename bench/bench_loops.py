"""Benchmark of loop closure (driftmap.core.loop_closure.search): work and time as the number of keyframes grows.

Synthetic site: a long strip of blurred random texture (a tunnel wall seen side-on), views of 64x32
pixels every 32 pixels; four mapping drives, each a forward pass over a random half of the strip,
with pixel jitter and noise, then patch normalisation. For N = 1,000, 4,000 and 16,000 keyframes it
prints the full shifted-SAD comparisons made against the N^2/2 of the paper's all-pairs search,
the time of each stage (median of runs) and the closures' precision/recall against the known
strip positions. On the smallest size it also times the naive all-pairs ``sad_matrix`` in the same
process and prints the speed-up.

With ``--site DIR`` (a site written by :func:`driftmap.sim.simulate_site`) it instead runs the
detector on the site's mapping drives (``--localisation`` adds the localisation drives as further
passes), keyframes every ``--spacing`` metres of ground-truth travel, and prints precision (both
ends of a closure within 3 m of each other) and recall (keyframes with an earlier eligible keyframe
within 1.5 m and 45 degrees of heading that got a correct closure) for the presets.

Usage: ``.venv/bin/python bench/bench_loops.py [--runs 3] [--sizes 1000 4000 16000]``
       ``.venv/bin/python bench/bench_loops.py --site OUT [--localisation] [--spacing 1.0]``
       ``.venv/bin/python bench/bench_loops.py --peaks [4000 20000 76000]``: only the choice of each query's
       distinct places, in the best groups of its row against suppression over the whole row
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.images import patch_normalise, preprocess
from driftmap.core.imaging.params import IMAGES_DEFAULT
from driftmap.core.imaging.sad import sad_matrix
from driftmap.core.loop_closure.params import LOOPS_DEFAULT, LOOPS_FAST, LOOPS_PAPER, LoopParams
from driftmap.core.loop_closure.peaks import top_local_maxima, top_local_maxima_whole_rows
from driftmap.core.loop_closure.search import LoopResult, detect_loops
from driftmap.formats.drive_folder import read_drive_folder
from driftmap.formats.frame_images import decode_gray

H, W, STEP_PX, MARGIN_PX = 32, 64, 32, 8
N_CHAINS = 4
TRUE_WITHIN = 2  # a closure is correct when its strip positions are at most this many views apart
SITE_TRUE_M = 3.0  # simulator: a closure is correct when its two keyframes are this close, metres
SITE_RECALLABLE_M = 1.5  # a keyframe is recallable with an earlier eligible one this close ...
SITE_RECALLABLE_RAD = np.pi / 4  # ... and heading this similar


def synthetic_site(n: int, seed: int = 0) -> tuple[list[NDArray[np.float32]], list[NDArray[np.int64]]]:
    """Chains of keyframes and the strip position (in views) of each."""
    rng = np.random.default_rng(seed)
    world = max(n // 2, 64)
    noise = rng.normal(0.0, 1.0, (H + 8, world * STEP_PX + W + 2 * MARGIN_PX)).astype(np.float32)
    strip = np.asarray(cv2.GaussianBlur(noise, (0, 0), 1.2), dtype=np.float32)
    chains, positions = [], []
    per = n // N_CHAINS
    for _ in range(N_CHAINS):
        start = int(rng.integers(0, world - per + 1))
        where = np.arange(start, start + per)
        xs = where * STEP_PX + MARGIN_PX + rng.integers(-2, 3, per)
        ys = 4 + rng.integers(-1, 2, per)
        views = np.stack([strip[y : y + H, x : x + W] for x, y in zip(xs, ys, strict=True)])
        views += rng.normal(0.0, 0.08, views.shape).astype(np.float32)
        chains.append(patch_normalise(views, 8))
        positions.append(where)
    return chains, positions


def precision_recall(
    result: LoopResult, positions: list[NDArray[np.int64]], params: LoopParams
) -> tuple[float, float]:
    """Closure precision, and the fraction of revisiting keyframes with a correct closure."""
    pairs = result.pairs()
    ok = np.array([abs(positions[a][i] - positions[b][j]) <= TRUE_WITHIN for a, i, b, j in pairs], dtype=bool)
    precision = float(ok.mean()) if ok.size else 1.0
    revisits = found = 0
    closed = {(int(a), int(i)) for (a, i, _, _), good in zip(pairs, ok, strict=True) if good}
    seen: set[int] = set()
    for c, where in enumerate(positions):
        for i, x in enumerate(where.tolist()):
            if x in seen and i >= params.seq_len - 1:
                revisits += 1
                found += (c, i) in closed
        seen.update(where.tolist())
    return precision, found / max(revisits, 1)


def load_site(
    site: Path, spacing_m: float, localisation: bool
) -> tuple[list[NDArray[np.float32]], list[NDArray[np.float64]], list[NDArray[np.float64]]]:
    """Keyframes (one per ``spacing_m`` of true travel) of a site's drives, with true x, y and yaw."""
    chains, poses, times = [], [], []
    kinds = ("mapping", "localisation") if localisation else ("mapping",)
    for path in sorted((site / "drives").iterdir()):
        drive = read_drive_folder(path)
        if drive.meta.kind not in kinds or path.name.count("-") > 1:  # skip obscured copies (loc-01-dust1)
            continue
        xy = np.array([(f.x_m, f.y_m) for f in drive.frames], dtype=np.float64)
        travel = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(xy, axis=0), axis=1))])
        keep = np.flatnonzero(np.diff(np.floor(travel / spacing_m), prepend=-1.0) > 0)
        images = np.stack([decode_gray(drive.frame_files[k].read_bytes()) for k in keep])
        chains.append(preprocess(images, IMAGES_DEFAULT))
        poses.append(np.array([(*xy[k], drive.frames[k].yaw_rad) for k in keep], dtype=np.float64))
        times.append(np.array([drive.frames[k].t_s for k in keep], dtype=np.float64))
    return chains, poses, times


def site_precision_recall(
    result: LoopResult, poses: list[NDArray[np.float64]], params: LoopParams
) -> tuple[float, float, int]:
    """Closure precision, recall of recallable keyframes, and their number."""
    pairs = result.pairs()
    ok = [np.hypot(*(poses[a][i, :2] - poses[b][j, :2])) <= SITE_TRUE_M for a, i, b, j in pairs]
    closed = {(int(a), int(i)) for (a, i, _, _), good in zip(pairs, ok, strict=True) if good}
    flat = np.concatenate(poses)
    start = np.cumsum([0] + [len(p) for p in poses])
    recallable = found = 0
    for c, chain_poses in enumerate(poses):
        for i, (x, y, yaw) in enumerate(chain_poses):
            limit = start[c] + max(0, i - params.recent_frames)
            if i < params.seq_len - 1 or limit == 0:
                continue
            near = np.hypot(flat[:limit, 0] - x, flat[:limit, 1] - y) <= SITE_RECALLABLE_M
            turn = np.abs((flat[:limit, 2] - yaw + np.pi) % (2 * np.pi) - np.pi)
            if np.any(near & (turn < SITE_RECALLABLE_RAD)):
                recallable += 1
                found += (c, i) in closed
    return (float(np.mean(ok)) if ok else float("nan")), found / max(recallable, 1), recallable


def bench_site(site: Path, spacing_m: float, localisation: bool) -> None:
    chains, poses, times = load_site(site, spacing_m, localisation)
    print(f"{site}: keyframes per drive {[len(c) for c in chains]} (every {spacing_m} m)")
    header = f"{'preset':>8} {'closures':>8} {'precision':>9} {'recall':>6} {'of':>5} {'full SAD':>9} {'d_t':>6} {'s':>6}"
    print(header)
    print("-" * len(header))
    for name, params in (("DEFAULT", LOOPS_DEFAULT), ("FAST", LOOPS_FAST), ("PAPER", LOOPS_PAPER)):
        t0 = time.perf_counter()
        res = detect_loops(chains, params, times)
        elapsed = time.perf_counter() - t0
        prec, rec, n_rec = site_precision_recall(res, poses, params)
        st = res.stats
        print(
            f"{name:>8} {len(res.closures):>8} {prec:>9.3f} {rec:>6.3f} {n_rec:>5} {st.n_full:>9,} "
            f"{st.d_t:>6.3f} {elapsed:>6.2f}"
        )


def bench_peaks(sizes: list[int], runs: int, block: int = 256, seed: int = 0) -> None:
    """Each query block's distinct places (top-k local maxima of its similarity rows) in the best groups
    of each row against suppression over whole rows, on ``block`` x N rows of a smooth random walk's
    similarities (neighbouring keyframes look alike, as in a tunnel)."""
    rng = np.random.default_rng(seed)
    params = LOOPS_DEFAULT
    print(
        f"\ntop-{params.top_k} local maxima (radius {params.nms_radius}) of {block} similarity rows of N keyframes"
    )
    header = f"{'N':>7} {'whole rows ms':>14} {'best groups ms':>15} {'speed-up':>9} {'same values':>12}"
    print(header)
    print("-" * len(header))
    for n in sizes:
        walk = np.cumsum(rng.normal(size=(n, 64)).astype(np.float32), axis=0)
        walk -= walk.mean(axis=0)
        desc = walk / np.linalg.norm(walk, axis=1, keepdims=True)
        rows = desc[rng.integers(0, n, block)] @ desc.T
        times: dict[str, list[float]] = {"whole": [], "groups": []}
        for _ in range(runs):
            for name, select in (("whole", top_local_maxima_whole_rows), ("groups", top_local_maxima)):
                t0 = time.perf_counter()
                got = select(rows, params.top_k, params.nms_radius)
                times[name].append(time.perf_counter() - t0)
                picked = np.sort(np.take_along_axis(rows, np.maximum(got, 0), axis=1), axis=1)
                if name == "whole":
                    want = picked
        whole, groups = (statistics.median(times[k]) * 1e3 for k in ("whole", "groups"))
        same = bool(np.array_equal(picked, want))
        print(f"{n:>7,} {whole:>14.1f} {groups:>15.1f} {whole / groups:>8.1f}x {same!s:>12}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="timed runs per size (median reported)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 4000, 16000])
    parser.add_argument("--site", type=Path, help="evaluate on this simulated site instead")
    parser.add_argument("--localisation", action="store_true", help="with --site: add localisation drives")
    parser.add_argument("--spacing", type=float, default=1.0, help="with --site: keyframe spacing, metres")
    parser.add_argument(
        "--peaks", type=int, nargs="*", help="only time the choice of distinct places per query at these N"
    )
    args = parser.parse_args()
    if args.peaks is not None:
        bench_peaks(args.peaks or [4000, 20000, 76000], args.runs)
        return
    if args.site is not None:
        bench_site(args.site, args.spacing, args.localisation)
        return
    params = LOOPS_DEFAULT
    print(
        f"{N_CHAINS} chains, 64x32 frames, shifts +-{params.sad.max_shift_x_px} x +-{params.sad.max_shift_y_px}"
    )
    header = (
        f"{'N':>6} {'N^2/2':>11} {'full SAD':>9} {'ratio':>7} {'coarse':>11} "
        f"{'desc s':>7} {'coarse s':>8} {'full s':>7} {'seq s':>7} {'total s':>8} {'prec':>5} {'recall':>6}"
    )
    print(header)
    print("-" * len(header))
    for n in args.sizes:
        chains, positions = synthetic_site(n)
        results = []
        for _ in range(args.runs):
            t0 = time.perf_counter()
            res = detect_loops(chains, params)
            results.append((time.perf_counter() - t0, res))
        total = statistics.median(t for t, _ in results)
        st = results[0][1].stats
        med = {k: statistics.median(r.stats.time_s[k] for _, r in results) for k in st.time_s}
        prec, rec = precision_recall(results[0][1], positions, params)
        half = n * (n - 1) // 2
        print(
            f"{n:>6} {half:>11,} {st.n_full:>9,} {st.n_full / half:>7.2%} {st.n_coarse:>11,} "
            f"{med['descriptors']:>7.2f} {med['coarse']:>8.2f} {med['full']:>7.2f} {med['sequence']:>7.2f} "
            f"{total:>8.2f} {prec:>5.3f} {rec:>6.3f}"
        )
    n = args.sizes[0]
    frames = np.concatenate(synthetic_site(n)[0])
    t0 = time.perf_counter()
    sad_matrix(frames, frames, params.sad)
    naive = (time.perf_counter() - t0) / 2  # the lower triangle is what all-pairs loop closure needs
    t0 = time.perf_counter()
    detect_loops(synthetic_site(n)[0], params)
    fast = time.perf_counter() - t0
    print(
        f"naive all-pairs sad_matrix on N = {n}: {naive:.2f} s (half of {n}x{n}) vs {fast:.2f} s: {naive / fast:.1f}x"
    )


if __name__ == "__main__":
    main()
