"""Benchmark of a place-recognition thumbnail's cost per frame with and without a lens (driftmap.core.imaging.views).

For each frame size (320x240 as the simulator records, 640x480, and [SSLAM]'s 944x800) a few hundred
grey frames are turned into 64x32 patch-normalised thumbnails one at a time, as mapping and the localiser do:
without a lens (``preprocess`` of the recorded frame: the baseline), through a radial-tangential pinhole
lens, and through a 180-degree equidistant fisheye (``f = W / pi``, narrowed to the 100-degree thumbnail view).
Prints the median milliseconds per frame of each, the ratio to the baseline run in the same process, the
one-off cost of building a lens's remap tables, and how many times they were built (once per lens and size).
One core.

Usage: ``.venv/bin/python bench/bench_thumbnails.py [--frames 300]``
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"  # one core: must be set before numpy is imported

import argparse  # noqa: E402
import math  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from driftmap.core.imaging.lens import Lens  # noqa: E402
from driftmap.core.imaging.params import IMAGES_DEFAULT  # noqa: E402
from driftmap.core.imaging.views import ViewMaps, thumbnails, view_maps  # noqa: E402

SIZES = ((320, 240), (640, 480), (944, 800))
DISTINCT_FRAMES = 16  # distinct frames cycled through (their content does not change the cost)


def lenses(width: int, height: int) -> dict[str, Lens]:
    """A barrel-distorted pinhole (about 75 degrees across) and a 180-degree fisheye of a frame size."""
    cx, cy = (width - 1) / 2, (height - 1) / 2
    f_pin = (width / 2) / math.tan(math.radians(37.5))
    f_fish = width / math.pi
    return {
        "pinhole": Lens(
            "pinhole", ((f_pin, 0.0, cx), (0.0, f_pin, cy), (0.0, 0.0, 1.0)), (-0.3, 0.1, 0.0, 0.0)
        ),
        "fisheye": Lens(
            "fisheye", ((f_fish, 0.0, cx), (0.0, f_fish, cy), (0.0, 0.0, 1.0)), (0.0, 0.0, 0.0, 0.0)
        ),
    }


def frames_of(width: int, height: int, rng: np.random.Generator) -> list[NDArray[np.uint8]]:
    """Smooth random grey (H, W) uint8 frames."""
    out = []
    for _ in range(DISTINCT_FRAMES):
        coarse = rng.uniform(0, 255, (height // 8, width // 8)).astype(np.float32)
        out.append(
            np.clip(cv2.resize(coarse, (width, height), interpolation=cv2.INTER_CUBIC), 0, 255).astype(
                np.uint8
            )
        )
    return out


def per_frame_ms(frames: list[NDArray[np.uint8]], lens: Lens | None, count: int) -> float:
    """Median milliseconds of one frame's thumbnail over ``count`` frames."""
    times = []
    for k in range(count):
        frame = frames[k % len(frames)]
        t0 = time.perf_counter()
        thumbnails(frame, IMAGES_DEFAULT, lens)
        times.append(time.perf_counter() - t0)
    return 1e3 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=300, help="frames timed per case (median reported)")
    args = parser.parse_args()
    rng = np.random.default_rng(0)
    cv2.setNumThreads(1)
    print(f"64x32 thumbnails, one frame at a time, median of {args.frames} frames; one core")
    header = f"{'frame':>8} {'lens':>8} {'ms/frame':>9} {'vs none':>8} {'tables ms':>10} {'builds':>7}"
    print(header)
    print("-" * len(header))
    for width, height in SIZES:
        frames = frames_of(width, height, rng)
        per_frame_ms(frames, None, 20)  # warm-up
        base = per_frame_ms(frames, None, args.frames)
        print(f"{width}x{height:<4} {'none':>8} {base:>9.3f} {1.0:>7.2f}x {'-':>10} {'-':>7}")
        for name, lens in lenses(width, height).items():
            t0 = time.perf_counter()
            ViewMaps(lens, (width, height))
            build_ms = 1e3 * (time.perf_counter() - t0)
            view_maps.cache_clear()
            ms = per_frame_ms(frames, lens, args.frames)
            builds = view_maps.cache_info().misses
            print(
                f"{width}x{height:<4} {name:>8} {ms:>9.3f} {ms / base:>7.2f}x {build_ms:>10.1f} {builds:>7}"
            )


if __name__ == "__main__":
    main()
