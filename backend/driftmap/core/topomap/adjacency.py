"""Connectivity of the stored map: nodes traced along the drives and the graph they make.

:func:`trace_nodes` walks the optimised drives once and lays nodes every N metres of tunnel, reusing nodes
that other passes made (paper III-A-4, Fig. 3). Drives are taken one after the other, each pose by pose:

* **Stand still.** A pose less than ``stationary_tol_m`` from the last moving pose is standing still: it
  belongs to the same node and adds no travel, so stops of any length make no nodes.
* **Join.** A pose within ``merge_radius_m`` of a node centre joins the nearest such node that is
  *plausible*; moving to a node other than the current one adds the graph edge between the two. Joining is
  heading-agnostic, so both travel directions and every repeated drive share nodes.
* **Plausible (the wall rule).** Tunnels behind a thin pillar, or either side of a pillar nose, can come
  closer than the merge radius. Let the drive have travelled ``s`` metres since it was closest to its current
  node. A candidate that the graph already reaches from the current node by a path longer than ``s`` plus
  both pose-to-centre distances plus two spacings (slack for a zigzag through a neighbour), yet shorter than
  ``wall_detour_m``, is refused: the vehicle cannot have driven there in that distance, so it lies across a
  wall. Unreached candidates (a junction with another drive's tunnels) and longer detours (a loop closing)
  are joined. A refusal costs a few duplicate nodes, a wrong join puts a shortcut through rock into the HMM;
  the detour limit is kept short so that genuine loops (pillar perimeters are longer) still close.
* **Create.** Otherwise, once the pose is ``spacing_m`` or more from the current node's centre, a new node is
  made exactly ``spacing_m`` from it on the trajectory (several if one step was long) and joined to it. The
  straight-line trigger equals the travelled distance along tunnels (bend radii >> N), and jitter, reversals
  and turning manoeuvres inside one node's area make no nodes and no self-edges.
* **Near misses.** Where a node would be made, a plausible node within ``CREATE_CLEARANCE`` merge radii is
  joined instead. Once every drive is traced, the points where a drive starts, ends (or breaks) and turns
  back are joined by an edge to the nearest plausible other node within ``END_CLEARANCE`` merge radii. Lanes
  cut corners and junctions differently, and vehicles start, stop and turn round in junctions; without these
  rules a duplicate node would sit beside an existing one, or a tunnel would stay unconnected to its junction.
* **Break.** A jump longer than ``max_frame_step_m`` between consecutive poses (a gap in the data) starts
  afresh without an edge across it.

The path lengths and HMM transitions of the traced graph are in :mod:`driftmap.core.topomap.distances`.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "CREATE_CLEARANCE",
    "END_CLEARANCE",
    "MIN_EDGE_M",
    "TURN_M",
    "GrowingGraph",
    "NodeTrace",
    "trace_nodes",
]

#: Shortest edge stored, metres: keeps every edge and path strictly positive so that a stored
#: distance is never confused with the implicit zero of a sparse matrix.
MIN_EDGE_M = 1e-6

#: A new node is not made within this many merge radii of a plausible existing node; that node is joined.
CREATE_CLEARANCE = 1.5

#: Where a drive starts, ends or turns back, it is joined to a plausible node within this many merge radii.
END_CLEARANCE = 2.0

#: Metres a drive must come back towards its current node for the furthest point to count as a turn.
TURN_M = 1.0


class GrowingGraph:
    """Undirected weighted graph that grows while a map is built and answers bounded path queries.

    Nodes are consecutive integers from 0; edge lengths are metres. ``version`` changes whenever an edge
    is added, so callers can cache path lengths between additions.
    """

    def __init__(self) -> None:
        self._nbrs: list[dict[int, float]] = []
        self.version = 0

    def add_node(self) -> int:
        """Add an isolated node and return its index."""
        self._nbrs.append({})
        return len(self._nbrs) - 1

    def add_edge(self, i: int, j: int, length_m: float) -> None:
        """Join nodes ``i`` and ``j`` (no-op for ``i == j`` or an existing edge)."""
        if i == j or j in self._nbrs[i]:
            return
        length_m = max(float(length_m), MIN_EDGE_M)
        self._nbrs[i][j] = length_m
        self._nbrs[j][i] = length_m
        self.version += 1

    def edge_length_m(self, i: int, j: int) -> float | None:
        """Length of edge (i, j) in metres, or None when the nodes are not joined directly."""
        return self._nbrs[i].get(j)

    def path_length_m(self, src: int, dst: int, limit_m: float) -> float:
        """Shortest-path length from ``src`` to ``dst`` in metres, or ``inf`` when longer than ``limit_m``."""
        if src == dst:
            return 0.0
        best = {src: 0.0}
        heap = [(0.0, src)]
        while heap:
            d, u = heapq.heappop(heap)
            if u == dst:
                return d
            if d > best[u]:
                continue
            for v, w in self._nbrs[u].items():
                nd = d + w
                if nd <= limit_m and nd < best.get(v, math.inf):
                    best[v] = nd
                    heapq.heappush(heap, (nd, v))
        return math.inf

    def edges(self) -> NDArray[np.int64]:
        """Every edge once as (E, 2) int64 node pairs with ``i < j``, sorted."""
        pairs = [(i, j) for i, nbrs in enumerate(self._nbrs) for j in nbrs if i < j]
        out = np.asarray(sorted(pairs), dtype=np.int64)
        return out.reshape(-1, 2)


@dataclass(frozen=True)
class NodeTrace:
    """Nodes and edges laid along the drives by :func:`trace_nodes`.

    Attributes:
        centres_m: (M, 2) float64 build-time node centres, survey frame, metres.
        edges: (E, 2) int64 node pairs ``i < j`` driven between directly.
        node: per chain, (N_i,) int64 node each pose was attached to while tracing.
        near: per chain, (N_i,) bool, True where the pose was within the merge radius of that node.
    """

    centres_m: NDArray[np.float64]
    edges: NDArray[np.int64]
    node: list[NDArray[np.int64]]
    near: list[NDArray[np.bool_]]


def _exit_fraction(px: float, py: float, x: float, y: float, cx: float, cy: float, radius: float) -> float:
    """Fraction t of the segment (px, py) -> (x, y) where it leaves the circle about (cx, cy)."""
    dx, dy, fx, fy = x - px, y - py, px - cx, py - cy
    a = dx * dx + dy * dy
    if a == 0.0:
        return 1.0
    b = fx * dx + fy * dy
    disc = max(b * b - a * (fx * fx + fy * fy - radius * radius), 0.0)
    return min(max((-b + math.sqrt(disc)) / a, 0.0), 1.0)


class _Tracer:
    """State of :func:`trace_nodes`: node centres, a hash grid over them, the growing graph."""

    def __init__(self, spacing_m: float, merge_radius_m: float, wall_detour_m: float) -> None:
        self.spacing, self.radius, self.wall = spacing_m, merge_radius_m, wall_detour_m
        self.cell = 2.0 * merge_radius_m
        self.xs: list[float] = []
        self.ys: list[float] = []
        self.grid: dict[int, list[int]] = {}
        self.graph = GrowingGraph()
        self.paths: dict[tuple[int, int], tuple[int, float]] = {}
        self.ends: list[tuple[float, float, int, float]] = []  # (x, y, node, travelled): starts, ends, turns

    def new_node(self, x: float, y: float, prev: int) -> int:
        node = self.graph.add_node()
        self.xs.append(x)
        self.ys.append(y)
        key = (math.floor(x / self.cell) << 32) + math.floor(y / self.cell)
        self.grid.setdefault(key, []).append(node)
        if prev >= 0:
            self.graph.add_edge(prev, node, math.hypot(x - self.xs[prev], y - self.ys[prev]))
        return node

    def join(self, cur: int, node: int) -> None:
        self.graph.add_edge(cur, node, math.hypot(self.xs[node] - self.xs[cur], self.ys[node] - self.ys[cur]))

    def plausible(self, cur: int, cand: int, reach_m: float) -> bool:
        """The wall rule: False if the graph reaches ``cand`` only by a short detour beyond ``reach_m``."""
        bound = reach_m + 2.0 * self.spacing  # slack: the path may zigzag through a neighbour node
        direct = self.graph.edge_length_m(cur, cand)
        if direct is not None and direct <= bound:
            return True
        cached = self.paths.get((cur, cand))
        if cached is not None and cached[0] == self.graph.version:
            path = cached[1]
        else:
            path = self.graph.path_length_m(cur, cand, self.wall)
            self.paths[(cur, cand)] = (self.graph.version, path)
        return path <= bound or math.isinf(path)

    def nearest(
        self, x: float, y: float, cur: int, travelled_m: float, clearance: float = 0.0, other: bool = False
    ) -> tuple[int, float]:
        """Nearest plausible node (``other``: but ``cur``) within the merge radius of (x, y), or (-1, inf).

        A ``clearance`` (in merge radii, at most 2) searches that far instead of the merge radius.
        """
        radius = (clearance or 1.0) * self.radius
        # a disc of the merge radius lies in 2 x 2 cells of twice that size; one of two merge radii in 3 x 3
        shift, span = (1.0, 3) if clearance else (0.5, 2)
        ix, iy = math.floor(x / self.cell - shift), math.floor(y / self.cell - shift)
        found: list[tuple[float, int]] = []
        for kx in range(ix, ix + span):
            for ky in range(iy, iy + span):
                for node in self.grid.get((kx << 32) + ky, ()):
                    d = math.hypot(x - self.xs[node], y - self.ys[node])
                    if d <= radius and not (other and node == cur):
                        found.append((d, node))
        found.sort()
        for d, node in found:
            if cur < 0 or node == cur or self.plausible(cur, node, travelled_m + d):
                return node, d
        return -1, math.inf

    def dist(self, x: float, y: float, node: int) -> float:
        return math.hypot(x - self.xs[node], y - self.ys[node])

    def stitch(self) -> None:
        """Join every drive's start, end and turning points to another node within the near-miss clearance.

        Done once all drives are traced, so that it does not depend on the order of the drives.
        """
        for x, y, cur, reach_m in self.ends:
            cand, _ = self.nearest(x, y, cur, reach_m, END_CLEARANCE, other=True)
            if cand >= 0:
                self.join(cur, cand)

    def run(
        self, xy_m: NDArray[np.float64], still_m: float, max_step_m: float
    ) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """Trace one chain of (N, 2) positions; returns its (N,) nodes and (N,) near flags."""
        n = xy_m.shape[0]
        node_of = np.empty(n, dtype=np.int64)
        near = np.zeros(n, dtype=bool)
        xl, yl = xy_m[:, 0].tolist(), xy_m[:, 1].tolist()
        # cur: current node; odo: odometer; s_ref, d_min: odometer and distance at the closest approach to cur
        cur, odo, s_ref, d_min, ax, ay, was_near = -1, 0.0, 0.0, 0.0, 0.0, 0.0, False
        # turn detection: the extreme distance from cur while moving away (out) or back (not out), and where
        out, d_ext, ext_x, ext_y = True, 0.0, 0.0, 0.0
        for i in range(n):
            x, y = xl[i], yl[i]
            if cur >= 0:
                step = math.hypot(x - ax, y - ay)
                if step < still_m:
                    node_of[i], near[i] = cur, was_near
                    continue
                if step > max_step_m:  # a gap in the data: end this stretch and start afresh
                    self.ends.append((ax, ay, cur, odo - s_ref + d_min))
                    cur = -1
                odo += step
            px, py, ax, ay = ax, ay, x, y
            reach, fresh = odo - s_ref + d_min, cur < 0
            cand, d = self.nearest(x, y, cur, reach)
            if cand < 0 and (cur < 0 or self.dist(x, y, cur) >= self.spacing):
                cand, d = self.nearest(x, y, cur, reach, CREATE_CLEARANCE)  # a near miss, not a new node
            if cand >= 0:
                if cand != cur:
                    if cur >= 0:
                        self.join(cur, cand)
                    cur, d_min, s_ref, out, d_ext = cand, d, odo, True, 0.0
                elif d < d_min:
                    d_min, s_ref = d, odo
                was_near = d <= self.radius
            elif cur < 0:
                cur, d_min, s_ref, was_near = self.new_node(x, y, -1), 0.0, odo, True
                out, d_ext = True, 0.0
            else:
                while self.dist(x, y, cur) >= self.spacing:
                    t = _exit_fraction(px, py, x, y, self.xs[cur], self.ys[cur], self.spacing)
                    px, py = px + t * (x - px), py + t * (y - py)
                    cur, d_min, out, d_ext = self.new_node(px, py, cur), 0.0, True, 0.0
                    s_ref = odo - math.hypot(x - px, y - py)
                d = self.dist(x, y, cur)
                if d < d_min:
                    d_min, s_ref = d, odo
                was_near = d <= self.radius
            node_of[i], near[i] = cur, was_near
            if fresh:
                self.ends.append((x, y, cur, 0.0))
            d = self.dist(x, y, cur)
            if out and d > d_ext:
                d_ext, ext_x, ext_y = d, x, y
            elif out and d < d_ext - TURN_M:  # turned back at (ext_x, ext_y)
                self.ends.append((ext_x, ext_y, cur, reach))
                out, d_ext = False, d
            elif not out:
                out, d_ext = (True, d) if d > d_ext + TURN_M else (False, min(d, d_ext))
        if cur >= 0:
            self.ends.append((ax, ay, cur, odo - s_ref + d_min))
        return node_of, near


def trace_nodes(
    chains_xy_m: Sequence[NDArray[np.float64]],
    spacing_m: float,
    merge_radius_m: float,
    wall_detour_m: float,
    stationary_tol_m: float,
    max_frame_step_m: float,
) -> NodeTrace:
    """Lay nodes along the drives and join them into a graph (rules in the module docstring).

    Args:
        chains_xy_m: per chain, (N_i, 2) float64 positions in time order, survey frame, metres.
        spacing_m: N, distance between consecutive new nodes, metres.
        merge_radius_m: a pose this close to a node centre may join it, metres (< spacing_m).
        wall_detour_m: detours shorter than this (but longer than the drive) mean a wall, metres.
        stationary_tol_m: moves shorter than this are standing still, metres.
        max_frame_step_m: longer jumps between consecutive poses split a chain, metres.

    Returns:
        The nodes, edges and per-pose attachments.
    """
    tracer = _Tracer(spacing_m, merge_radius_m, wall_detour_m)
    nodes, near = [], []
    for xy in chains_xy_m:
        chain_nodes, chain_near = tracer.run(
            np.asarray(xy, dtype=np.float64), stationary_tol_m, max_frame_step_m
        )
        nodes.append(chain_nodes)
        near.append(chain_near)
    tracer.stitch()
    centres = np.stack([np.asarray(tracer.xs), np.asarray(tracer.ys)], axis=1).reshape(-1, 2)
    return NodeTrace(centres_m=centres, edges=tracer.graph.edges(), node=nodes, near=near)
