"""How a map build's costs grow with the mine: per stage wall time, CPU time and peak memory, and exponents.

For each size asked for (tiny, small and medium by default; large and mine, ~20 km, when named), the seed's
simulated site (``bench/out/site-SIZE-SEED``, simulated on first use) is imported into a fresh SQLite store
and mapped as ``driftmap map build`` does (:func:`driftmap.services.maps.build_site_map`, stage 1 in
``--workers`` processes), in a child process of its own so that each size's memory is its own. A sampler
thread in the child reads every 0.1 s the stage the build last reported and the CPU time and resident memory
of the child and its worker processes (``/proc``); the CPU used between two samples goes to the stage then
running. Stages: loading the stored drives, odometry (with the frame statistics of the place database's
filter), loop closure, pose graph, topological map (with its place database), storing the new version.

Prints per size: tunnel length, frames and keyframes, the map's error against the simulator's truth (every
mapping frame's distance to its true position), and per stage wall s, CPU s and peak MB (the build's whole
process tree); then per stage the growth exponent of its wall and CPU time between consecutive sizes
(``log(cost ratio) / log(length ratio)``: 1 is linear, the issue's target is at most 1.1 from medium up) and
the CPU seconds per km. (How the loop-closure search's comparisons grow: ``bench_mapping.py --growth``.)

Usage: ``PYTHONPATH=backend:. .venv/bin/python bench/bench_scaling.py [--sizes tiny small medium large mine]
[--seed 7] [--preset paper|fast] [--workers 2]``
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import multiprocessing
import os
import resource
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' helpers

from tests.sim_site import create_site, import_folders

from bench_mapping import PRESETS, mapping_folders, mapping_truth, site_dir
from driftmap.config import Settings
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.store.storage import Storage
from proc_tree import cpu_s, descendants, rss_mb

STAGES = ("loading", "odometry", "loop closure", "pose graph", "topological map", "storing")
SAMPLE_S = 0.1


@dataclass
class StageCost:
    """What one stage of one build used: wall and CPU seconds, peak resident MB of the process tree."""

    wall_s: float = 0.0
    cpu_s: float = 0.0
    peak_mb: float = 0.0


@dataclass
class SizeResult:
    """One size's build: its tunnel length (km), frames, keyframes and each stage's cost."""

    size: str
    km: float
    frames: int
    keyframes: int
    costs: dict[str, StageCost]
    error_m: tuple[float, float, float]  # mean, median, max distance of every frame to its true position


@dataclass
class Sampler:
    """Samples the build's stage, CPU and memory from a thread (see the module doc)."""

    stage: str = "loading"
    costs: dict[str, StageCost] = field(default_factory=lambda: {s: StageCost() for s in STAGES})
    _stop: threading.Event = field(default_factory=threading.Event)

    def report(self, stage: str, fraction: float) -> None:
        """The build's progress callback: the stage it is in (after the topological map: storing)."""
        self.stage = "storing" if stage == "topological map" and fraction >= 1.0 else stage

    def run(self) -> None:
        me = os.getpid()
        last_t, last_cpu = time.perf_counter(), _tree_cpu_s(me)
        while not self._stop.wait(SAMPLE_S):
            now, cpu = time.perf_counter(), _tree_cpu_s(me)
            cost = self.costs.setdefault(self.stage, StageCost())
            cost.wall_s += now - last_t
            cost.cpu_s += cpu - last_cpu
            cost.peak_mb = max(cost.peak_mb, sum(rss_mb(pid) for pid in descendants(me)))
            last_t, last_cpu = now, cpu

    def stop(self) -> None:
        self._stop.set()


def _tree_cpu_s(me: int) -> float:
    """CPU seconds of this process, its ended children and its live descendants."""
    own = resource.getrusage(resource.RUSAGE_SELF)
    ended = resource.getrusage(resource.RUSAGE_CHILDREN)
    live = sum(cpu_s(pid) for pid in descendants(me) if pid != me)
    return own.ru_utime + own.ru_stime + ended.ru_utime + ended.ru_stime + live


def measure(size: str, seed: int, preset: str, workers: int) -> SizeResult:
    """One size's build in this process (run it in a child)."""
    site = site_dir(size, seed)
    meta = json.loads((site / "site.json").read_text())
    with tempfile.TemporaryDirectory(prefix=f"bench-scaling-{size}-") as tmp:
        storage = Storage.open(Settings(data_dir=Path(tmp)))
        try:
            create_site(storage, site, "bench")
            import_folders(storage, "bench", mapping_folders(site))
            sampler = Sampler()
            thread = threading.Thread(target=sampler.run, daemon=True)
            thread.start()
            with storage.blobs.batch() as batch, storage.db.session() as session:
                _version, build = map_service.build_site_map(
                    session,
                    storage.blobs,
                    batch,
                    site_service.get_site(session, "bench"),
                    PRESETS[preset],
                    sampler.report,
                    workers=workers,
                )
            sampler.stop()
            thread.join()
        finally:
            storage.close()
    km = float(meta["tunnel_length_m"]) / 1000.0
    frames, keyframes = int(build.stats["frames"]), int(build.stats["keyframes"])
    truth = mapping_truth(site)
    error = np.concatenate(
        [np.linalg.norm(w[:, :2] - t, axis=1) for w, t in zip(build.wTi, truth, strict=True)]
    )
    costs = {s: sampler.costs.get(s, StageCost()) for s in STAGES}
    return SizeResult(
        size, km, frames, keyframes, costs, (float(error.mean()), float(np.median(error)), float(error.max()))
    )


def _child(size: str, seed: int, preset: str, workers: int, out: multiprocessing.Queue) -> None:  # type: ignore[type-arg]
    out.put(measure(size, seed, preset, workers))


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--sizes", nargs="+", default=["tiny", "small", "medium"])
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--preset", choices=sorted(PRESETS), default="paper")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument(
        "--plot", type=Path, help="draw each stage's CPU time against tunnel length here (PNG)"
    )
    args = parser.parse_args()
    context = multiprocessing.get_context("spawn")
    results: list[SizeResult] = []
    for size in args.sizes:
        site_dir(size, args.seed)  # simulated here, outside the measured child
        queue = context.Queue()
        child = context.Process(target=_child, args=(size, args.seed, args.preset, args.workers, queue))
        child.start()
        results.append(queue.get())
        child.join()
        _print_size(results[-1])
    _print_growth(results)
    if args.plot is not None:
        plot(results, args.plot)


def plot(results: list[SizeResult], path: Path) -> None:
    """Log-log curves of each stage's CPU seconds (and the build's wall seconds) against tunnel length."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    km = [r.km for r in results]
    fig, ax = plt.subplots(figsize=(7.5, 4.8))
    for stage in STAGES[1:]:
        ax.plot(km, [max(r.costs[stage].cpu_s, 1e-2) for r in results], marker="o", label=f"{stage} (CPU)")
    walls = [sum(c.wall_s for c in r.costs.values()) for r in results]
    ax.plot(km, walls, marker="s", color="black", linestyle="--", label="whole build (wall)")
    ax.plot(
        km, [walls[0] * k / km[0] for k in km], color="grey", linestyle=":", label="linear from the first"
    )
    for r, wall in zip(results, walls, strict=True):
        ax.annotate(r.size, (r.km, wall), textcoords="offset points", xytext=(4, 6))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("tunnel length, km")
    ax.set_ylabel("seconds")
    ax.set_title("Map build cost by stage against the size of the mine")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _print_size(r: SizeResult) -> None:
    costs = r.costs.values()
    print(
        f"{r.size}: {r.km:.2f} km, {r.frames:,} frames, {r.keyframes:,} keyframes; build "
        f"{sum(c.wall_s for c in costs):.1f} s wall, {sum(c.cpu_s for c in costs):.1f} s CPU, "
        f"peak {max(c.peak_mb for c in costs):,.0f} MB; mapping error mean {r.error_m[0]:.2f} m (median "
        f"{r.error_m[1]:.2f}, max {r.error_m[2]:.2f})"
    )
    for stage, c in r.costs.items():
        print(f"  {stage:<16} wall {c.wall_s:8.1f} s  CPU {c.cpu_s:8.1f} s  peak {c.peak_mb:8,.0f} MB")


def _exponent(a: float, b: float, size_a: float, size_b: float) -> float:
    """log(b / a) / log(size_b / size_a): how a cost grows with a size (1 is linear)."""
    if a <= 0 or b <= 0:
        return float("nan")
    return math.log(b / a) / math.log(size_b / size_a)


def _print_growth(results: list[SizeResult]) -> None:
    if len(results) < 2:
        return
    print(
        "growth exponent of each stage's wall / CPU time with tunnel length (and of its CPU time with the"
        " mapping frames), between consecutive sizes:"
    )
    for stage in STAGES:
        parts = []
        for a, b in itertools.pairwise(results):
            ca, cb = a.costs[stage], b.costs[stage]
            wall = _exponent(ca.wall_s, cb.wall_s, a.km, b.km)
            cpu = _exponent(ca.cpu_s, cb.cpu_s, a.km, b.km)
            per_frame = _exponent(ca.cpu_s, cb.cpu_s, a.frames, b.frames)
            parts.append(f"{a.size}->{b.size} {wall:.2f} / {cpu:.2f} ({per_frame:.2f})")
        per_km = ", ".join(f"{r.size} {r.costs[stage].cpu_s / r.km:.1f}" for r in results)
        print(f"  {stage:<16} {'; '.join(parts)}   (CPU s per km: {per_km})")


if __name__ == "__main__":
    main()
