"""Benchmark of the HMM localiser (driftmap.core.localisation.localiser) on one core: pruned filter vs full comparison.

A synthetic 2,000-node map (a 50 x 40 grid of tunnels, 5 m spacing, 3 frames a node, 64x32 patch-normalised
thumbnails, reference positions 1 m apart and every grid line as a mapped path with a pose every 0.5 m, as
a stored map has; ``--grid 200x100`` for 20,000 nodes) is localised against a drive of a few hundred frames at 10 Hz snaking along the grid (about
6 m/s), starting with a global (unknown) belief. Prints the median and 95th-percentile milliseconds per
frame and the fraction of frames on the right node for the filter as driftmap runs it (top ``n_t`` prior
states plus probes) and for the full-comparison baseline (every node, every frame, no pruning), and the
ratio of their medians. Target: median <= 10 ms per frame.

Two more runs feed raw 320x240 uint8 camera frames (the textures enlarged, with sensor noise) so that the
localiser pre-processes each frame itself: once with holistic SAD and once with SESAME salient masks (paper
001 eq. 5-7: patch entropy at 160x76 and three patch sizes per frame, masked SAD of eq. 6), to show what
SESAME adds per frame. The last run is the product's default on a live vehicle: each frame arrives as JPEG
bytes and is decoded, SESAME-masked and localised with the simulator camera's ground-plane odometry (the
floor region shows a textured floor moving with the vehicle); its time per frame is split into decode,
odometry and the rest. Target: median <= 15 ms per frame.

Usage: ``.venv/bin/python bench/bench_localise.py [--frames 300] [--baseline-frames 60] [--grid 50x40]``
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS"):
    os.environ[_var] = "1"  # one core: must be set before numpy is imported

import argparse  # noqa: E402
import statistics  # noqa: E402
import time  # noqa: E402

import cv2  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from driftmap.core.imaging.images import patch_normalise  # noqa: E402
from driftmap.core.localisation import hmm  # noqa: E402
from driftmap.core.localisation.localiser import Localiser  # noqa: E402
from driftmap.core.localisation.map import LocaliserMap, mapped_paths  # noqa: E402
from driftmap.core.localisation.motion import OdometryFeed  # noqa: E402
from driftmap.core.sesame.masks import SESAME_DEFAULT  # noqa: E402
from driftmap.core.topomap.distances import shortest_paths  # noqa: E402
from driftmap.sim.rig import CameraRig  # noqa: E402

GRID = (50, 40)  # columns, rows: 2,000 nodes (--grid)
SPACING_M = 5.0
FRAMES_PER_NODE = 3
DT_S = 0.1  # 10 Hz
FRAMES_PER_NODE_STEP = 8  # the vehicle moves one node every 8 frames: 6.25 m/s
NOISE = 12.0  # query noise, grey levels (textures have std 40)


def grid_map(rng: np.random.Generator, cols: int, rows: int) -> tuple[LocaliserMap, NDArray[np.float32]]:
    """The synthetic map of a ``cols`` x ``rows`` grid and the (M, 32, 64) raw textures its thumbnails were
    made from (M = cols * rows)."""
    m = cols * rows
    raw = rng.normal(0.0, 1.0, (m, 32, 64)).astype(np.float32)
    tex = np.stack([cv2.GaussianBlur(r, (0, 0), 1.2) for r in raw])
    tex = np.asarray(128 + 40 * tex / tex.std(axis=(1, 2), keepdims=True), dtype=np.float32)
    views = tex[:, None] + rng.normal(0.0, NOISE, (m, FRAMES_PER_NODE, 32, 64)).astype(np.float32)
    thumbs = patch_normalise(views.reshape(-1, 32, 64))
    ids = np.arange(m).reshape(rows, cols)
    edges = np.concatenate(
        [
            np.stack([ids[:, :-1].ravel(), ids[:, 1:].ravel()], 1),
            np.stack([ids[:-1].ravel(), ids[1:].ravel()], 1),
        ]
    ).astype(np.int64)
    col, row = np.divmod(np.arange(m), cols)[::-1]
    centres = np.column_stack([col * SPACING_M, row * SPACING_M]).astype(np.float64)
    along = (np.arange(FRAMES_PER_NODE) - (FRAMES_PER_NODE - 1) / 2) * 1.0  # references 1 m apart along x
    # mapped paths like a stored map's: every grid line driven once, a pose every 0.5 m
    lines = [
        np.column_stack([np.arange(0.0, (cols - 1) * SPACING_M + 1e-9, 0.5), np.full_like(xs, r * SPACING_M)])
        for r in range(rows)
        for xs in [np.arange(0.0, (cols - 1) * SPACING_M + 1e-9, 0.5)]
    ] + [
        np.column_stack([np.full_like(ys, c * SPACING_M), ys])
        for c in range(cols)
        for ys in [np.arange(0.0, (rows - 1) * SPACING_M + 1e-9, 0.5)]
    ]
    path_xy_m, path_segments = mapped_paths(
        np.concatenate(lines), np.r_[0, np.cumsum([len(line) for line in lines])].astype(np.int64)
    )
    lmap = LocaliserMap(
        thumbs=thumbs,
        node_ptr=np.arange(0, FRAMES_PER_NODE * m + 1, FRAMES_PER_NODE, dtype=np.int64),
        centres_m=centres,
        adjacency_m=shortest_paths(m, edges, np.full(edges.shape[0], SPACING_M), 50.0),
        max_adjacency_m=50.0,
        edges=edges,
        ref_xy_m=np.repeat(centres, FRAMES_PER_NODE, axis=0)
        + np.c_[np.tile(along, m), np.zeros(m * FRAMES_PER_NODE)],
        path_xy_m=path_xy_m,
        path_segments=path_segments,
    )
    return lmap, tex


def snake(n_nodes: int, cols: int, rows: int) -> list[int]:
    """Nodes of a drive along the rows of a ``cols`` x ``rows`` grid, turning at the ends (boustrophedon)."""
    out: list[int] = []
    for r in range(rows):
        along = range(cols) if r % 2 == 0 else range(cols - 1, -1, -1)
        out.extend(r * cols + c for c in along)
        if len(out) >= n_nodes:
            break
    return out[:n_nodes]


def raw_frame(tex: NDArray[np.float32], rng: np.random.Generator) -> NDArray[np.uint8]:
    """A 320x240 uint8 camera frame of a (32, 64) texture with sensor noise."""
    big = cv2.resize(tex, (320, 240), interpolation=cv2.INTER_LINEAR)
    return np.clip(big + rng.normal(0.0, NOISE, big.shape), 0, 255).astype(np.uint8)


def drive(
    loc: Localiser, tex: NDArray[np.float32], grid: tuple[int, int], frames: int, seed: int, raw: bool = False
) -> tuple[list[float], float]:
    """Per-frame milliseconds (first, global frame excluded) and the fraction of frames on the right node,
    driving along the rows of the ``grid`` (columns, rows)."""
    rng = np.random.default_rng(seed)
    path = snake(frames // FRAMES_PER_NODE_STEP + 1, *grid)
    ms, right = [], 0
    for k in range(frames):
        node = path[k // FRAMES_PER_NODE_STEP]
        if raw:
            query: NDArray[np.generic] = raw_frame(tex[node], rng)
        else:
            query = patch_normalise(tex[node] + rng.normal(0.0, NOISE, tex.shape[1:]).astype(np.float32))
        est = loc.step(query, k * DT_S)
        right += est.node == node
        if k:
            ms.append(est.ms)
    return ms, right / frames


def floor_strip(rng: np.random.Generator, length_px: int) -> NDArray[np.uint8]:
    """A long (length_px, 320) uint8 gravel-like floor, rows along the drive."""
    noise = rng.normal(0.0, 1.0, (length_px, 320)).astype(np.float32)
    floor = sum(cv2.GaussianBlur(noise, (0, 0), s) * w for s, w in ((1.0, 0.6), (3.0, 1.0), (8.0, 1.0)))
    return np.asarray(np.clip(128 + 30 * floor / floor.std(), 0, 255), dtype=np.uint8)


def drive_with_odometry(
    loc: Localiser, tex: NDArray[np.float32], grid: tuple[int, int], frames: int, seed: int
) -> tuple[dict[str, list[float]], float]:
    """Per-frame milliseconds of JPEG decode, odometry and the rest, and the fraction on the right node."""
    rng = np.random.default_rng(seed)
    path = snake(frames // FRAMES_PER_NODE_STEP + 1, *grid)
    camera = CameraRig().camera_model
    feed = OdometryFeed(camera)
    x, y, w, h = camera.ground_roi_px
    px_per_frame = 6  # floor rows the ROI content moves per frame
    floor = floor_strip(rng, frames * px_per_frame + h + 1)
    parts: dict[str, list[float]] = {"decode": [], "odometry": [], "localise": [], "total": []}
    right = 0
    for k in range(frames):
        node = path[k // FRAMES_PER_NODE_STEP]
        raw = raw_frame(tex[node], rng)
        start = floor.shape[0] - h - k * px_per_frame  # content moves down as the vehicle drives on
        raw[y : y + h, x : x + w] = floor[start : start + h, x : x + w]
        jpeg = cv2.imencode(".jpg", raw, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes()
        t0 = time.perf_counter()
        frame = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_GRAYSCALE)
        t1 = time.perf_counter()
        motion = feed.step(frame, k * DT_S)
        t2 = time.perf_counter()
        est = loc.step(frame, k * DT_S, motion=motion)
        t3 = time.perf_counter()
        right += est.node == node
        if k:
            for name, ms in zip(parts, (t1 - t0, t2 - t1, t3 - t2, t3 - t0), strict=True):
                parts[name].append(ms * 1e3)
    return parts, right / frames


def main() -> None:
    parser = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    parser.add_argument("--frames", type=int, default=300, help="frames localised by the pruned filter")
    parser.add_argument("--baseline-frames", type=int, default=60, help="frames for the full comparison")
    parser.add_argument(
        "--grid",
        default="x".join(map(str, GRID)),
        help="COLSxROWS of the synthetic map (200x100: 20,000 nodes)",
    )
    args = parser.parse_args()
    cols, rows = (int(v) for v in args.grid.split("x"))
    cv2.setNumThreads(1)
    lmap, tex = grid_map(np.random.default_rng(0), cols, rows)
    m = lmap.n_nodes
    print(
        f"{m} nodes x {FRAMES_PER_NODE} frames, 64x32 thumbnails, {cols}x{rows} grid, {SPACING_M:g} m spacing"
    )
    full = hmm.HmmParams(n_t=m, n_probe=0, lost_frames=0)
    runs = {  # name: (params, frames, raw camera frames, SESAME)
        f"pruned (n_t={hmm.DEFAULT.n_t}, probes={hmm.DEFAULT.n_probe})": (
            hmm.DEFAULT,
            args.frames,
            False,
            False,
        ),
        "full comparison": (full, args.baseline_frames, False, False),
        "pruned, raw 320x240 frames": (hmm.DEFAULT, args.frames, True, False),
        "pruned, raw frames + SESAME": (hmm.DEFAULT, args.frames, True, True),
    }
    medians = []
    print(f"{'filter':>30} {'frames':>6} {'median ms':>9} {'p95 ms':>7} {'on node':>7}")
    for name, (params, frames, raw, sesame) in runs.items():
        loc = Localiser(lmap, params, sesame=SESAME_DEFAULT if sesame else None)
        ms, right = drive(loc, tex, (cols, rows), frames, seed=1, raw=raw)
        med = statistics.median(ms)
        medians.append(med)
        p95 = float(np.percentile(ms, 95))
        print(f"{name:>30} {frames:>6} {med:>9.2f} {p95:>7.2f} {right:>7.1%}")
    loc = Localiser(lmap, sesame=SESAME_DEFAULT)
    parts, right = drive_with_odometry(loc, tex, (cols, rows), args.frames, seed=1)
    med = statistics.median(parts["total"])
    p95 = float(np.percentile(parts["total"], 95))
    print(f"{'JPEG + SESAME + odometry':>30} {args.frames:>6} {med:>9.2f} {p95:>7.2f} {right:>7.1%}")
    split = ", ".join(f"{k} {statistics.median(v):.2f}" for k, v in parts.items() if k != "total")
    print(f"  median ms per part: {split}")
    print(f"full / pruned median time: {medians[1] / medians[0]:.1f}x (target: pruned <= 10 ms/frame)")
    print(f"SESAME / holistic on raw frames: {medians[3] / medians[2]:.2f}x")
    print(f"JPEG + SESAME + odometry / raw frames + SESAME: {med / medians[3]:.2f}x (target: <= 15 ms/frame)")


if __name__ == "__main__":
    main()
