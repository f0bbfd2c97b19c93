"""Benchmark of the shifted SAD (driftmap.core.imaging.sad) against a naive per-pair Python loop.

Prints image comparisons per second (one query against M references, shifts +-4 x / +-2 y, median
of several runs) for 64x32 and 32x24 patch-normalised images and M = 2,000 and 6,000, next to a
naive loop run in the same process on the same data, and the ratio. Also checks the two agree.

Usage: ``.venv/bin/python bench/bench_sad.py [--runs 5]``
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.images import patch_normalise
from driftmap.core.imaging.params import SadParams
from driftmap.core.imaging.sad import sad_matrix, sad_one_to_many

MAX_DX, MAX_DY = 4, 2
NAIVE_PAIRS = 300  # the naive loop is timed on this many references and scaled


def naive_sad(
    query: NDArray[np.float32], refs: NDArray[np.float32], max_dx: int, max_dy: int
) -> NDArray[np.float64]:
    """Per-pair, per-shift Python loop: the obvious implementation of eq. 3."""
    height, width = query.shape
    out = np.empty(len(refs))
    for j, ref in enumerate(refs):
        best = np.inf
        for dy in range(-max_dy, max_dy + 1):
            for dx in range(-max_dx, max_dx + 1):
                qa = query[max(0, -dy) : height - max(0, dy), max(0, -dx) : width - max(0, dx)]
                rb = ref[max(0, dy) : height + min(0, dy), max(0, dx) : width + min(0, dx)]
                best = min(best, float(np.mean(np.abs(qa - rb))))
        out[j] = best
    return out


def median_time(fn: object, runs: int) -> float:
    times = []
    for _ in range(runs):
        t0 = time.perf_counter()
        fn()  # type: ignore[operator]
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5, help="timed runs per case (median reported)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    params = SadParams(max_shift_x_px=MAX_DX, max_shift_y_px=MAX_DY)
    print(f"shifts +-{MAX_DX} x, +-{MAX_DY} y; median of {args.runs} runs; comparisons per second")
    header = f"{'image':>7} {'refs':>6} {'vectorised/s':>13} {'naive/s':>9} {'ratio':>6} {'max |diff|':>10}"
    print(header)
    print("-" * len(header))
    for width, height in ((64, 32), (32, 24)):
        raw = rng.integers(0, 256, size=(6001, height, width), dtype=np.uint8)
        imgs = patch_normalise(raw, patch_px=8 if width >= 64 else 4)
        query, all_refs = imgs[0], imgs[1:]
        naive_refs = all_refs[:NAIVE_PAIRS]
        naive_t = median_time(lambda q=query, r=naive_refs: naive_sad(q, r, MAX_DX, MAX_DY), 3)
        naive_rate = NAIVE_PAIRS / naive_t
        for m in (2000, 6000):
            refs = all_refs[:m]
            sad_one_to_many(query, refs, params)  # warm-up
            t = median_time(lambda q=query, r=refs: sad_one_to_many(q, r, params), args.runs)
            fast = sad_one_to_many(query, refs[:NAIVE_PAIRS], params).d
            err = float(np.max(np.abs(fast - naive_sad(query, refs[:NAIVE_PAIRS], MAX_DX, MAX_DY))))
            rate = m / t
            print(
                f"{width}x{height:<4} {m:>6} {rate:>13,.0f} {naive_rate:>9,.0f} {rate / naive_rate:>5.1f}x "
                f"{err:>10.1e}"
            )
        block = imgs[:64]
        t = median_time(lambda b=block, r=all_refs[:2000]: sad_matrix(b, r, params), 1)
        print(f"{width}x{height:<4} confusion block 64x2000: {64 * 2000 / t:,.0f} comparisons/s")


if __name__ == "__main__":
    main()
