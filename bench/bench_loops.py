"""Benchmark of loop closure (driftmap.core.loops): work and time as the number of keyframes grows.

Synthetic site: a long strip of blurred random texture (a tunnel wall seen side-on), views of 64x32
pixels every 32 pixels; four mapping drives, each a forward pass over a random half of the strip,
with pixel jitter and noise, then patch normalisation. For N = 1,000, 4,000 and 16,000 keyframes it
prints the full shifted-SAD comparisons made against the N^2/2 of the paper's all-pairs search,
the time of each stage (median of runs) and the closures' precision/recall against the known
strip positions. On the smallest size it also times the naive all-pairs ``sad_matrix`` in the same
process and prints the speed-up.

Usage: ``.venv/bin/python bench/bench_loops.py [--runs 3] [--sizes 1000 4000 16000]``
"""

from __future__ import annotations

import argparse
import statistics
import time

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.images import patch_normalise
from driftmap.core.loops import LOOPS_DEFAULT, LoopParams, LoopResult, detect_loops
from driftmap.core.sad import sad_matrix

H, W, STEP_PX, MARGIN_PX = 32, 64, 32, 8
N_CHAINS = 4
TRUE_WITHIN = 2  # a closure is correct when its strip positions are at most this many views apart


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="timed runs per size (median reported)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[1000, 4000, 16000])
    args = parser.parse_args()
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
