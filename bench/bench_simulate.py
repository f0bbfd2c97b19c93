"""Benchmark: the synthetic mine simulator (``driftmap.sim``).

Targets (issue): a small site in under 2 minutes, a medium site in under 10 minutes on a 2-core machine,
i.e. at least 40 rendered frames per second overall. Prints:

1. the renderer alone in this process: frames/s of ray casting, and with PNG encoding;
2. whole sites through ``simulate_site`` (planning, world, rendering on all cores, obscured copies,
   writing): wall time, rendered and written frames, rendered frames/s, and the ratio to the target.

Usage: ``python bench/bench_simulate.py [--sizes small,medium] [--frames 200]``.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from driftmap.sim import plan_site, simulate_site
from driftmap.sim.frames import encode_png
from driftmap.sim.render import Renderer
from driftmap.sim.world import build_world

TARGET_S = {"tiny": 30.0, "small": 120.0, "medium": 600.0, "large": 2400.0}


def bench_renderer(frames: int) -> None:
    site = plan_site(7, "small")
    t0 = time.perf_counter()
    world = build_world(site.layout, 7)
    t_world = time.perf_counter() - t0
    renderer = Renderer(world, site.rig)
    poses = site.poses[0]
    idx = np.linspace(0, len(poses.t) - 1, frames).astype(int)
    local = poses.xy[idx] - np.asarray(world.origin_xy)
    t0 = time.perf_counter()
    images = [
        renderer.render(float(x), float(y), float(a), 1.0, [7, int(i)])
        for (x, y), a, i in zip(local, poses.yaw[idx], idx, strict=True)
    ]
    t_render = time.perf_counter() - t0
    t0 = time.perf_counter()
    sizes = [len(encode_png(img)) for img in images]
    t_png = time.perf_counter() - t0
    print(f"world build (small site): {t_world:.2f} s")
    print(
        f"render only, 1 process:   {frames / t_render:7.1f} frames/s ({1000 * t_render / frames:.1f} ms/frame)"
    )
    print(
        f"render + PNG, 1 process:  {frames / (t_render + t_png):7.1f} frames/s "
        f"(PNG {1000 * t_png / frames:.1f} ms, {np.mean(sizes) / 1024:.0f} KiB/frame)"
    )


def bench_site(size: str) -> None:
    out = Path(tempfile.mkdtemp(prefix=f"bench-sim-{size}-"))
    try:
        cpu0 = (
            resource.getrusage(resource.RUSAGE_SELF).ru_utime
            + resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
        )
        summary = simulate_site(out / "site", seed=7, size=size)
        cpu1 = (
            resource.getrusage(resource.RUSAGE_SELF).ru_utime
            + resource.getrusage(resource.RUSAGE_CHILDREN).ru_utime
        )
        disk = sum(p.stat().st_size for p in (out / "site").rglob("*") if p.is_file())
    finally:
        shutil.rmtree(out, ignore_errors=True)
    s = summary.seconds
    print(
        f"{size:>6} site: {summary.tunnel_length_m:6.0f} m of tunnel, {len(summary.drives)} drives, "
        f"{summary.frames_rendered} frames rendered, {summary.frames_written} written, {disk / 2**20:.0f} MiB"
    )
    print(
        f"        wall {s:6.1f} s (target {TARGET_S[size]:.0f} s, ratio {s / TARGET_S[size]:.2f}), "
        f"{summary.frames_rendered / s:5.1f} rendered frames/s, cpu {cpu1 - cpu0:.0f} s on {os.cpu_count()} cores"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="small,medium", help="comma-separated site sizes to simulate")
    parser.add_argument(
        "--frames", type=int, default=200, help="frames for the single-process renderer bench"
    )
    args = parser.parse_args()
    print(f"load average before: {os.getloadavg()[0]:.2f}")
    bench_renderer(args.frames)
    for size in [s for s in args.sizes.split(",") if s]:
        bench_site(size)


if __name__ == "__main__":
    main()
