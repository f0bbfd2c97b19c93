"""Benchmark of ground-plane odometry's per-frame cost on [SSLAM]'s 944x800 180-degree fisheye.

Renders a short stretch of a mapping drive through the simulator's ``wide180`` camera (perfect ride), then
matches consecutive frames three ways, one core, each in the same process:

- **baseline**: the frames undistorted beforehand (outside the timing) and matched as an ideal pinhole;
- **lens** (what driftmap does): the raw fisheye frames, each undistorted only over the window the bird's-eye
  grid samples (``core/odometry/grid.py``: remap tables built once per camera);
- **full frame**: each raw frame undistorted whole, then matched as the baseline (the naive way).

Prints the median milliseconds per step of each, its ratio to the baseline, the median cost of the window
remap and of a whole-frame remap alone, and the window's share of the frame.

Usage: ``.venv/bin/python bench/bench_lens_odometry.py [--frames 80]``
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"  # one core: must be set before numpy is imported

import argparse  # noqa: E402
import dataclasses  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402
from collections.abc import Callable  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from driftmap.core.imaging.lens import lens_maps  # noqa: E402
from driftmap.core.odometry.drive import match_frames  # noqa: E402
from driftmap.core.odometry.grid import match_grid  # noqa: E402
from driftmap.core.odometry.params import ODOMETRY_DEFAULT  # noqa: E402
from driftmap.sim.render import Renderer  # noqa: E402
from driftmap.sim.site import plan_site  # noqa: E402
from driftmap.sim.world import build_world  # noqa: E402

cv2.setNumThreads(1)


def rendered(n: int) -> tuple[list[NDArray[np.uint8]], object]:
    """``n`` consecutive moving frames of the tiny site's first mapping drive through ``wide180``, and its rig."""
    site = plan_site(4, "tiny", "wide180")
    world = build_world(site.layout, 4)
    renderer = Renderer(world, site.rig)
    poses = site.poses[0]
    step = np.hypot(*np.diff(poses.xy, axis=0).T)
    start = int(np.flatnonzero(step > 0.2)[0])
    origin = np.asarray(world.origin_xy)
    frames = []
    for k in range(start, start + n):
        x, y = poses.xy[k] - origin
        frames.append(renderer.render(float(x), float(y), float(poses.yaw[k]), 1.0, [4, k]))
    return frames, site.rig


def median_ms(fn: Callable[[], object], repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1000)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=80)
    args = parser.parse_args()
    frames, rig = rendered(args.frames)
    lens_cam = rig.camera_model  # type: ignore[attr-defined]
    assert lens_cam.lens is not None
    size = (lens_cam.width_px, lens_cam.height_px)
    whole = lens_maps(lens_cam.lens, size, (0, 0, *size))
    pinhole_cam = dataclasses.replace(lens_cam, lens=None)
    undistorted = [whole.apply(f) for f in frames]

    def per_step(cam: object, seq: list[NDArray[np.uint8]]) -> float:
        matched = match_frames(seq, cam, ODOMETRY_DEFAULT)  # type: ignore[arg-type]
        return float(np.median(matched.ms_per_step))

    baseline = per_step(pinhole_cam, undistorted)
    with_lens = per_step(lens_cam, frames)
    t0 = time.perf_counter()
    full = [whole.apply(f) for f in frames]
    full_remap_ms = (time.perf_counter() - t0) * 1000 / len(frames)
    full_frame = per_step(pinhole_cam, full) + full_remap_ms
    grid = match_grid(lens_cam, ODOMETRY_DEFAULT)
    window = grid.undistort
    assert window is not None
    window_ms = median_ms(lambda: window.apply(frames[0]), 50)
    whole_ms = median_ms(lambda: whole.apply(frames[0]), 50)
    _, _, w, h = window.window
    print(
        f"{args.frames} wide180 frames 944x800, one core; median ms per odometry step (frame preparation included)"
    )
    print(f"  baseline (pre-undistorted, pinhole)   {baseline:7.2f} ms  1.00x")
    print(f"  lens: window undistorted per frame    {with_lens:7.2f} ms  {with_lens / baseline:.2f}x")
    print(f"  full frame undistorted, then matched  {full_frame:7.2f} ms  {full_frame / baseline:.2f}x")
    print(
        f"  remap alone: window {w}x{h} ({100 * w * h / (size[0] * size[1]):.0f} % of the frame) {window_ms:.2f} ms,"
        f" whole frame {whole_ms:.2f} ms ({whole_ms / max(window_ms, 1e-9):.1f}x)"
    )


if __name__ == "__main__":
    main()
