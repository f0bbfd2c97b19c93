"""Benchmark: map compression (paper III-A-4) on synthetic sites of 0.4, 1.5 and 6 km of tunnel.

Target (topomap issue): a 6 km site (~1,200 nodes at 5 m, 20 mapping chains of ~2,000 frames) builds in well
under 5 s. Each site is a grid of drifts and crosscuts (loops, 3- and 4-way junctions) driven by walks that
head for the nearest tunnel not yet driven in that direction (so every tunnel is driven both ways), keeping
right with lateral offsets in [-1.5, 0.3] m, a slowly varying trajectory error of up to ~0.6 m, stops of
50-500 frames and short reversals.

Baseline, run in the same process on the same chains: the naive quadratic version of the same compression,
i.e. every pose compared with every node made so far (no spatial index, no wall rule), every frame assigned by
a dense frames x nodes distance matrix, and the dense all-pairs shortest-path matrix A of the paper (no
distance limit). Prints medians over several runs and the ratio naive/driftmap, then checks each synthetic
map against the true network: stored A(x, y) against the along-tunnel distance. With --real, also times the
M3500 ground-truth trajectory from shared/data/posegraphs (a 2-D "Manhattan" world whose blocks are a few
metres across, finer than N: a timing row, not a tunnel map).

With --site SIZE, the localisation database on a simulated site's map (its drives prepared and solved once):
the map compressed with each node's frames chosen by the SESAME database (Algorithm 1, then spaced views),
all nodes in lockstep (the product's path) against the same selector called on one node at a time (the path
before it), with the two maps' chosen frames compared.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import sys
import time
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import TypeVar

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bench_mapping import mapping_drives, site_dir
from driftmap.core.mapping.pipeline import MAPPING_DEFAULT, prepare_drives, solve_map
from driftmap.core.topomap.build import build_topomap
from driftmap.core.topomap.database import database_selector
from driftmap.core.topomap.model import TOPOMAP_PAPER, NodeFrames, TopoMap, TopoMapParams, per_node

F64 = NDArray[np.float64]
T = TypeVar("T")
SIZES_KM = (0.4, 1.5, 6.0)
RUNS = 5
M3500 = (
    Path(__file__).resolve().parents[2]
    / "shared"
    / "data"
    / "posegraphs"
    / "M3500_olson_groundtruth_nodes.dat"
)


def grid_network(length_m: float) -> tuple[F64, list[tuple[int, int]]]:
    """Junctions (J, 2) and tunnels (pairs of junctions) of an n x n grid about ``length_m`` long in total."""
    n = 2
    while 2 * (n + 1) * n * 40.0 < length_m:  # pillars of at least ~40 m between drifts
        n += 1
    spacing = length_m / (2 * n * (n - 1))
    ij = np.array([(i, j) for i in range(n) for j in range(n)], dtype=np.float64)
    tunnels = [(a, b) for a in range(n * n) for b in range(a + 1, n * n) if np.abs(ij[a] - ij[b]).sum() == 1]
    return ij * spacing, tunnels


def route(
    junctions: F64,
    tunnels: list[tuple[int, int]],
    budget_m: float,
    driven: set[tuple[int, int]],
    rng: np.random.Generator,
) -> list[int]:
    """A walk over junctions: to the nearest tunnel not yet driven in that direction, then at random."""
    nbrs: dict[int, list[int]] = {}
    for a, b in tunnels:
        nbrs.setdefault(a, []).append(b)
        nbrs.setdefault(b, []).append(a)
    walk = [int(rng.integers(len(junctions)))]
    length = 0.0
    while length < budget_m:
        path = _to_undriven(walk[-1], nbrs, driven)
        if not path:  # everything driven: wander without turning back
            here = walk[-1]
            path = [int(rng.choice([v for v in nbrs[here] if len(walk) < 2 or v != walk[-2]] or nbrs[here]))]
        for nxt in path:
            driven.add((walk[-1], nxt))
            length += float(np.linalg.norm(junctions[nxt] - junctions[walk[-1]]))
            walk.append(nxt)
    return walk


def _to_undriven(start: int, nbrs: dict[int, list[int]], driven: set[tuple[int, int]]) -> list[int]:
    """Junctions from ``start`` (excluded) through the nearest tunnel not yet driven that way."""
    parent = {start: start}
    queue = [start]
    for here in queue:
        for v in nbrs[here]:
            if (here, v) not in driven:
                path = [v, here]
                while path[-1] != start:
                    path.append(parent[path[-1]])
                return path[-2::-1]
            if v not in parent:
                parent[v] = here
                queue.append(v)
    return []


def drive_route(points: F64, rng: np.random.Generator) -> F64:
    """(N, 3) poses along a centre-line polyline: lanes, trajectory error, stops and reversals."""
    seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
    s_line = np.r_[0.0, np.cumsum(seg)]
    dense_s = np.arange(0.0, s_line[-1], 0.1)
    xy = np.column_stack([np.interp(dense_s, s_line, points[:, k]) for k in (0, 1)])
    box = np.ones(31) / 31  # smooth the corners over ~3 m so that lanes turn like a vehicle
    xy_s = np.column_stack([np.convolve(np.pad(xy[:, k], 15, mode="edge"), box, "valid") for k in (0, 1)])
    tangent = np.gradient(xy_s, axis=0)
    yaw = np.arctan2(tangent[:, 1], tangent[:, 0])
    normal = np.column_stack([-np.sin(yaw), np.cos(yaw)])
    phase = rng.uniform(0, 2 * np.pi, 3)
    # keep right of the centre line (-0.6 m) and wander: lanes in [-1.5, 0.3] m, opposite passes ~1-2 m apart
    lane = -0.6 + 0.7 * np.sin(dense_s / 37.0 + phase[0]) + 0.2 * np.sin(dense_s / 7.0 + phase[1])
    error = 0.4 * np.column_stack([np.sin(dense_s / 90.0 + phase[2]), np.cos(dense_s / 110.0 + phase[0])])
    xy_v = xy_s + lane[:, None] * normal + error
    s, out = 0.0, []
    while s < dense_s[-1]:
        r = rng.random()
        if r < 0.0006:  # a stop of 50-500 frames
            out.extend([s] * int(rng.integers(50, 500)))
        elif r < 0.0012:  # a short reversal
            back = float(rng.uniform(3.0, 8.0))
            out.extend(np.linspace(s, max(s - back, 0.0), int(back / 0.2)).tolist())
            out.extend(np.linspace(max(s - back, 0.0), s, int(back / 0.2)).tolist())
        s += float(rng.uniform(0.2, 0.5))
        out.append(s)
    idx = np.clip(np.searchsorted(dense_s, np.asarray(out)), 0, dense_s.size - 1)
    poses = np.column_stack([xy_v[idx], yaw[idx]])
    poses[:, :2] += rng.normal(0.0, 0.01, (idx.size, 2))  # jitter, also while standing still
    return poses


def synthetic_site(length_km: float, seed: int = 0) -> list[F64]:
    """Mapping chains over a grid site of ``length_km`` km: ~20 chains of ~2,000 frames per 6 km."""
    rng = np.random.default_rng(seed)
    junctions, tunnels = grid_network(1000.0 * length_km)
    n_chains = max(2, round(20 * length_km / 6.0))
    driven: set[tuple[int, int]] = set()
    chains = []
    for _ in range(n_chains):
        walk = route(junctions, tunnels, 2.2 * 1000.0 * length_km / n_chains, driven, rng)
        chains.append(drive_route(junctions[walk], rng))
    return chains


def naive_build(chains: list[F64], params: TopoMapParams) -> tuple[F64, NDArray[np.intp], F64]:
    """The quadratic baseline: every pose against every node, dense frame assignment, dense all-pairs A."""
    cap = sum(len(c) for c in chains)
    centres = np.empty((cap, 2))
    m, edges = 0, set[tuple[int, int]]()
    for chain in chains:
        cur = -1
        for x, y in chain[:, :2]:
            d = np.hypot(centres[:m, 0] - x, centres[:m, 1] - y)
            near = int(np.argmin(d)) if m else -1
            if near >= 0 and d[near] <= params.merge_radius_m:
                if cur >= 0 and near != cur:
                    edges.add((min(cur, near), max(cur, near)))
                cur = near
            elif cur < 0 or d[cur] >= params.spacing_m:
                centres[m] = (x, y)
                if cur >= 0:
                    edges.add((cur, m))
                cur, m = m, m + 1
    centres = centres[:m]
    xy = np.concatenate(chains)[:, :2]
    frame_node = np.concatenate(  # every frame's node: dense frames x nodes distances
        [
            np.argmin(np.linalg.norm(xy[i : i + 4096, None] - centres[None], axis=2), axis=1)
            for i in range(0, len(xy), 4096)
        ]
    )
    e = np.asarray(sorted(edges)).reshape(-1, 2)
    w = np.linalg.norm(centres[e[:, 0]] - centres[e[:, 1]], axis=1)
    a = dijkstra(csr_array((w, (e[:, 0], e[:, 1])), shape=(m, m)), directed=False)
    return centres, frame_node, np.asarray(a)  # A: dense (M, M), as in the paper


def path_check(topo: TopoMap, junctions: F64, tunnels: list[tuple[int, int]]) -> tuple[float, int, int]:
    """Stored A against true along-tunnel distances for node pairs under 40 m apart by tunnel.

    Returns the median |A - true| in metres, the pairs whose A is > 6 m shorter (shortcuts through rock)
    and the pairs whose A is > 10 m longer or missing (broken or detoured connections).
    """
    pts, rows, cols, lengths = [*junctions], [], [], []
    for a, b in tunnels:  # the true network, sampled every ~0.5 m
        k = max(1, int(np.linalg.norm(junctions[b] - junctions[a]) / 0.5))
        ids = [a]
        for i in range(1, k):
            pts.append(junctions[a] + (junctions[b] - junctions[a]) * i / k)
            ids.append(len(pts) - 1)
        ids.append(b)
        step = float(np.linalg.norm(junctions[b] - junctions[a])) / k
        rows += ids[:-1]
        cols += ids[1:]
        lengths += [step] * k
    net = csr_array((lengths, (rows, cols)), shape=(len(pts), len(pts)))
    _, proj = cKDTree(np.asarray(pts)).query(topo.centres_m)
    true = dijkstra(net, directed=False, indices=proj, limit=60.0)[:, proj]
    stored = topo.adjacency_m.toarray()
    stored[stored == 0] = np.inf
    np.fill_diagonal(stored, 0.0)
    close = true < 40.0
    found = close & np.isfinite(stored)
    err = float(np.median(np.abs(stored[found] - true[found])))
    return err, int((close & (stored < true - 6.0)).sum()), int((close & (stored > true + 10.0)).sum())


def timed(fn: Callable[[], T], runs: int) -> tuple[float, T]:
    """Median wall time of ``runs`` calls, seconds, and the last result."""
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times), out


def site_database(size: str, seed: int, runs: int) -> None:
    """The database's frame choice on a simulated site's map: all nodes in lockstep vs one node at a time."""
    drives = mapping_drives(site_dir(size, seed))
    params = MAPPING_DEFAULT
    prepared = prepare_drives(drives, params, workers=2)
    wTi = solve_map(prepared, drives, params).wTi
    stats = prepared.frame_stats
    if stats is None:
        raise SystemExit("the default mapping parameters have the database off: nothing to measure")
    counts = [t.shape[0] for t in prepared.thumbs]
    chain_ptr = np.r_[0, np.cumsum(counts)].astype(np.int64)
    select = database_selector(
        stats, np.concatenate(prepared.thumbs), chain_ptr, params.database, params.loops.sad
    )

    def one_node(cands: NodeFrames, k: int) -> NDArray[np.int64]:
        return select([cands], k)[0]

    per_node_frames = max(params.topomap.frames_per_node, params.database.frames_per_node)
    topo_params = dataclasses.replace(params.topomap, frames_per_node=per_node_frames)
    chains, quality = list(wTi), list(prepared.confidence)
    lockstep_s, topo = timed(
        partial(build_topomap, chains, quality=quality, params=topo_params, select_frames=select), runs
    )
    alone_s, alone = timed(
        partial(build_topomap, chains, quality=quality, params=topo_params, select_frames=per_node(one_node)),
        max(1, runs // 2),
    )
    same = np.array_equal(topo.chosen_ptr, alone.chosen_ptr) and np.array_equal(topo.chosen, alone.chosen)
    print(
        f"\nLocalisation database of the {size} site, seed {seed}: {sum(counts):,} frames, "
        f"{topo.n_nodes:,} nodes"
    )
    print(f"{'frames chosen':>32} {'seconds':>8}")
    print(f"{'all nodes in lockstep (default)':>32} {lockstep_s:>8.2f}")
    print(f"{'one node at a time':>32} {alone_s:>8.2f}")
    print(
        f"one at a time / lockstep: {alone_s / lockstep_s:.1f}x; {topo.chosen.size:,} reference frames, "
        f"{'the same' if same else 'NOT the same'} in both maps "
        f"(median of {runs} and {max(1, runs // 2)} runs)"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=RUNS)
    parser.add_argument("--real", action="store_true", help="also the M3500 ground-truth grid world")
    parser.add_argument(
        "--site", help="also the localisation database on this simulated site size (e.g. medium)"
    )
    parser.add_argument("--seed", type=int, default=7, help="the site's seed")
    args = parser.parse_args()
    if args.site:
        site_database(args.site, args.seed, args.runs)
    sites = [(f"{km:g} km grid", synthetic_site(km, seed=1), km) for km in SIZES_KM]
    if args.real and M3500.exists():
        sites.append(("M3500 ground truth", [np.loadtxt(M3500)], 0.0))
    print(
        f"{'site':>20} {'chains':>6} {'frames':>7} {'nodes':>6} {'edges':>6} {'junct':>5} {'A nnz':>8} "
        f"{'build s':>8} {'naive s':>8} {'naive/ours':>10}"
    )
    checks = []
    for name, chains, km in sites:
        ours_s, topo = timed(partial(build_topomap, chains, params=TOPOMAP_PAPER), args.runs)
        naive_s, _ = timed(partial(naive_build, chains, TOPOMAP_PAPER), max(1, args.runs // 2))
        frames = sum(len(c) for c in chains)
        print(
            f"{name:>20} {len(chains):>6} {frames:>7} {topo.n_nodes:>6} {len(topo.edges):>6} "
            f"{int((topo.degree() >= 3).sum()):>5} {topo.adjacency_m.nnz:>8} {ours_s:>8.3f} {naive_s:>8.3f} "
            f"{naive_s / ours_s:>10.1f}"
        )
        if km:
            checks.append((name, *path_check(topo, *grid_network(1000.0 * km))))
    print(
        f"(median of {args.runs} runs; naive median of {max(1, args.runs // 2)}; target: 6 km well under 5 s)"
    )
    print("\nstored A vs true along-tunnel distance, node pairs < 40 m apart:")
    for name, err, short, broken in checks:
        print(f"{name:>20}  median |A - true| {err:.2f} m, shortcuts {short}, broken/detoured {broken}")


if __name__ == "__main__":
    main()
