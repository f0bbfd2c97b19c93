"""Benchmark: the pose-graph back end on the standard 2-D benchmarks of ``shared/data/posegraphs``.

1. M3500 clean: the default batch solver's time, final error, ATE against ground truth (reference 0.794 m).
2. M3500 with 20 % and 50 % false closures by the protocol of ``posegraphs/README.md`` (both ends
   uniform, x, y ~ N(0, 0.3 m), theta ~ N(0, 10 deg), a true closure's information, fixed seed): ATE
   against the outlier-free solution per kernel. Target: <= 0.05 m with the default kernel (DCS).
   The share of accepted true / false closures is printed too; it does not tell which maps are good.
3. Batch LM vs iSAM2 fed frame by frame (QR) on Intel, city10000 (iSAM2 with ``--slow``) and MIT Killian:
   final error and time.
4. Re-solving M3500 after a grounding edit: warm start vs from scratch.
5. The pose graph of a simulated site's map build (``--site medium --seed 7``; stages 1-3 once, then the
   pose-graph stage with its calibration rounds per run), ``--graphs`` of: ``frame``, a node per frame;
   ``lm``, the keyframe-level graph (a node where a closure, grounding or anchor needs one and every
   ``node_spacing_m``) solved by Levenberg-Marquardt; ``dogleg``, the same by Powell's dog leg;
   ``default``, the same by the default solvers (LM, continued by the dog leg where LM runs out of
   iterations; the dog leg for the last solve). Nodes, pose-graph seconds, the last solve's iterations, each map's error against the
   simulator's truth, and per pair the ratio of times and the largest difference between the maps. On the
   20 km site: ``--site mine --graphs lm,dogleg,default --runs 1`` (stages 1-3 take about 20 minutes).

Times are medians over ``--runs`` runs where one run takes under 5 s. Sections 1-4 skip cleanly without the
data; section 5 simulates the site on first use (``bench/out``).
"""

from __future__ import annotations

import argparse
import dataclasses
import itertools
import statistics
import sys
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench_mapping import mapping_drives, mapping_truth, site_dir
from driftmap.core.graph.alignment import umeyama_2d
from driftmap.core.graph.constraints import (
    GroundingConstraint,
    LoopConstraint,
    PoseGraphParams,
    PoseGraphResult,
)
from driftmap.core.graph.posegraph import PoseGraphSession, optimise_pose_graph
from driftmap.core.mapping.pipeline import MAPPING_DEFAULT, prepare_drives, solve_map
from driftmap.formats.g2o import read_g2o, read_pose_table, to_pose_graph

DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data" / "posegraphs"
KERNELS = ("none", "huber", "cauchy", "dcs", "geman_mcclure")
TARGET_ATE_M = 0.05
SEED = 0


def ate_m(wTi: np.ndarray, reference: np.ndarray) -> float:
    """RMS position error after a rigid alignment onto ``reference``, metres."""
    R, t, _ = umeyama_2d(wTi[:, :2], reference[:, :2])
    return float(np.sqrt(((wTi[:, :2] @ R.T + t - reference[:, :2]) ** 2).sum(axis=1).mean()))


def timed(run: Callable[[], PoseGraphResult], runs: int) -> tuple[PoseGraphResult, float]:
    """Run once, and again up to ``runs`` times when a run is cheap (< 5 s); median wall time."""
    times, result = [], None
    for _ in range(runs):
        t0 = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - t0)
        if times[0] > 5.0:
            break
    assert result is not None
    return result, statistics.median(times)


def false_closures(num_poses: int, count: int, infos: np.ndarray, seed: int) -> list[LoopConstraint]:
    """Random wrong closures by the protocol (both ends uniform, not neighbours)."""
    rng = np.random.default_rng(seed)
    out: list[LoopConstraint] = []
    while len(out) < count:
        i, j = (int(v) for v in rng.integers(0, num_poses, 2))
        if abs(i - j) > 1:
            x, y, theta = rng.normal(0, 0.3), rng.normal(0, 0.3), rng.normal(0, np.deg2rad(10.0))
            info = infos[rng.integers(len(infos))]
            out.append(LoopConstraint((0, i), (0, j), (1.0, 1.0, 1.0), (x, y, theta), information=info))
    return out


def m3500(runs: int, with_gnc: bool) -> None:
    chains, closures = to_pose_graph(read_g2o(DATA / "M3500_olson.g2o"))
    truth = read_pose_table(DATA / "M3500_olson_groundtruth_nodes.dat")
    plain = PoseGraphParams(loop_kernel="none")
    clean, clean_s = timed(lambda: optimise_pose_graph(chains, closures, (), plain), runs)
    print(f"\nM3500 clean ({len(truth)} poses, {len(closures)} closures), batch ({plain.solver}):")
    print(
        f"  time {clean_s:.2f} s, {clean.iterations} iterations, error {clean.initial_error:.1f} -> {clean.final_error:.3f}"
    )
    print(f"  ATE vs ground truth {ate_m(clean.all_poses(), truth):.3f} m (reference 0.794 m)")
    reference = clean.all_poses()
    infos = np.array([c.information for c in closures])
    kernels = (*KERNELS, "gnc_tls") if with_gnc else KERNELS
    for share in (0.2, 0.5):
        wrong = false_closures(len(truth), round(share * len(closures)), infos, SEED)
        print(
            f"\nM3500 + {share:.0%} false closures ({len(wrong)} added, seed {SEED}), from the odometry guess:"
        )
        print(f"  {'kernel':<14} {'ATE vs clean m':>14} {'ATE vs gt m':>12} {'time s':>8} {'iters':>6} {'true acc':>9} {'false acc':>9}")  # fmt: skip
        for kernel in kernels:
            params = PoseGraphParams(loop_kernel=kernel)  # type: ignore[arg-type]
            result, seconds = timed(partial(optimise_pose_graph, chains, closures + wrong, (), params), runs)
            poses, accepted = result.all_poses(), result.closure_accepted
            print(
                f"  {kernel:<14} {ate_m(poses, reference):>14.4f} {ate_m(poses, truth):>12.3f} {seconds:>8.2f}"
                f" {result.iterations:>6} {accepted[: len(closures)].mean():>9.1%} {accepted[len(closures) :].mean():>9.1%}"
            )  # fmt: skip


def batch_vs_incremental(runs: int, slow: bool) -> None:
    print("\nBatch LM vs iSAM2 fed frame by frame (QR, then an LM polish), plain least squares:")
    print(
        f"  {'graph':<12} {'poses':>6} {'closures':>8} {'LM error':>10} {'LM s':>7} {'iSAM2 error':>12} {'iSAM2 s':>8}"
    )
    plain, incremental = (
        PoseGraphParams(loop_kernel="none", solver="lm"),
        PoseGraphParams(loop_kernel="none", solver="isam2"),
    )
    for name in ("intel_sesync", "city10000", "MITb"):
        chains, closures = to_pose_graph(read_g2o(DATA / f"{name}.g2o"))
        row = f"  {name:<12} {sum(c.num_frames for c in chains):>6} {len(closures):>8}"
        lm, lm_s = timed(partial(optimise_pose_graph, chains, closures, (), plain), runs)
        row += f" {lm.final_error:>10.2f} {lm_s:>7.2f}"
        if name == "city10000" and not slow:
            print(row + "   (iSAM2 with --slow: about 5 min)")
            continue
        inc, inc_s = timed(partial(optimise_pose_graph, chains, closures, (), incremental), 1)
        print(row + f" {inc.final_error:>12.2f} {inc_s:>8.2f}")


def warm_start(runs: int) -> None:
    chains, closures = to_pose_graph(read_g2o(DATA / "M3500_olson.g2o"))
    truth = read_pose_table(DATA / "M3500_olson_groundtruth_nodes.dat")
    frames = np.linspace(0, len(truth) - 1, 12).astype(int)
    marks = [GroundingConstraint((0, int(f)), (float(truth[f, 0]), float(truth[f, 1])), 0.5) for f in frames]
    warm_s, scratch_s, diffs = [], [], []
    for run in range(runs):
        session = PoseGraphSession(chains, closures, marks)
        session.solve()
        moved = dataclasses.replace(marks[5], xy_m=(marks[5].xy_m[0] + 1.0 + run, marks[5].xy_m[1] - 0.5))
        session.move_grounding(5, moved.xy_m)
        t0 = time.perf_counter()
        warm = session.solve()
        warm_s.append(time.perf_counter() - t0)
        t0 = time.perf_counter()
        scratch = optimise_pose_graph(chains, closures, list(session.groundings.values()))
        scratch_s.append(time.perf_counter() - t0)
        diffs.append(float(np.abs(warm.all_poses()[:, :2] - scratch.all_poses()[:, :2]).max()))
    print("\nM3500 with 12 groundings, one moved by about 1 m, DCS, re-solve (wall time incl. graph set-up):")
    print(
        f"  warm start {statistics.median(warm_s):.2f} s vs from scratch {statistics.median(scratch_s):.2f} s"
    )
    print(f"  largest position difference {max(diffs):.2e} m")


def site_graphs(size: str, seed: int, runs: int, graphs: list[str]) -> None:
    site = site_dir(size, seed)
    drives = mapping_drives(site)
    truth = mapping_truth(site)
    prepared = prepare_drives(drives, MAPPING_DEFAULT, workers=2)
    default = MAPPING_DEFAULT.graph
    variants = {
        "frame": ("frame-level (a node per frame)", dataclasses.replace(default, node_spacing_m=0.0)),
        "lm": (
            "keyframe-level, Levenberg-Marquardt",
            dataclasses.replace(default, solver="lm", last_solver="lm"),
        ),
        "dogleg": (
            "keyframe-level, Powell's dog leg",
            dataclasses.replace(default, solver="dogleg", last_solver="dogleg"),
        ),
        "default": (
            f"keyframe-level (default, {default.node_spacing_m:g} m, {default.solver}/{default.last_solver})",
            default,
        ),
    }
    print(f"\nMap build of {size} seed {seed} ({sum(t.shape[0] for t in truth):,} frames), pose-graph stage")
    print("(first solve and calibration rounds), median of the runs; error = distance to the true position:")
    print(f"  {'graph':<44}{'nodes':>8}{'seconds':>9}{'last iters':>11}{'mean err m':>12}{'max err m':>11}")
    maps, seconds = [], []
    for key in graphs:
        label, graph = variants[key]
        params = dataclasses.replace(MAPPING_DEFAULT, graph=graph)
        times = []
        for _ in range(runs):
            build = solve_map(prepared, drives, params)
            times.append(float(build.stats["pose_graph_s"]))
        poses = np.concatenate([w[:, :2] for w in build.wTi])
        error = np.linalg.norm(poses - np.concatenate(truth), axis=1)
        maps.append(poses)
        seconds.append(statistics.median(times))
        nodes, iterations = int(build.stats["graph_nodes"]), int(build.stats["graph_iterations"])
        print(
            f"  {label:<44}{nodes:>8,}{seconds[-1]:>9.2f}{iterations:>11}{error.mean():>12.3f}{error.max():>11.3f}"
        )
    for (a, map_a, s_a), (b, map_b, s_b) in itertools.combinations(
        zip(graphs, maps, seconds, strict=True), 2
    ):
        print(
            f"  {a} / {b}: {s_a / s_b:.1f}x the time; the two maps differ by at most "
            f"{np.linalg.norm(map_a - map_b, axis=1).max():.3f} m"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3, help="runs per cheap measurement (median)")
    parser.add_argument("--gnc", action="store_true", help="also GNC-TLS (minutes per run)")
    parser.add_argument("--slow", action="store_true", help="also iSAM2 on city10000 (minutes)")
    parser.add_argument("--site", default="medium", help="simulated site size of section 5 ('none': skip)")
    parser.add_argument("--seed", type=int, default=7, help="its seed")
    parser.add_argument(
        "--graphs", default="frame,lm,default", help="section 5's graphs, of frame, lm, dogleg and default"
    )
    args = parser.parse_args()
    unknown = set(args.graphs.split(",")) - {"frame", "lm", "dogleg", "default"}
    if unknown:
        parser.error(f"--graphs: unknown {', '.join(sorted(unknown))}; of frame, lm, dogleg and default")
    if (DATA / "M3500_olson.g2o").exists():
        m3500(args.runs, args.gnc)
        batch_vs_incremental(args.runs, args.slow)
        warm_start(args.runs)
    else:
        print(f"sections 1-4 skipped: {DATA} is absent")
    if args.site != "none":
        site_graphs(args.site, args.seed, args.runs, args.graphs.split(","))


if __name__ == "__main__":
    main()
