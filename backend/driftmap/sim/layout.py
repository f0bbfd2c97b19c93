"""The tunnel network of a synthetic extraction level, in mine-grid metres.

A ladder-style level: a perimeter loop of drives, production cross-cuts between its long sides, short
drawpoints off the production tunnels (herringbone, slanted 60 deg), a dump (tip) spur and an access
drive ending at a ventilation door. The centreline graph has junction nodes (degree >= 3) and
dead-end nodes (drawpoints, the dump, the access end); each edge carries its centreline polyline from
node ``a`` to node ``b``. Walls are the boundary of the union of the tunnels' footprints.

Drawpoints slant forward with respect to the direction in which the planar face on their side is
walked with that face on the left (see :mod:`driftmap.sim.motion`), so an LHD following a face turns
into every drawpoint by 60 deg and reverses out by 60 deg. Everything is deterministic per seed.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
import shapely
from shapely.geometry import LineString, Point, Polygon

from driftmap.sim.geometry import FloatArray, heading_at, point_at, polyline_length, project, split_at
from driftmap.sim.params import LayoutParams, SiteSize

__all__ = ["Edge", "EdgeKind", "Layout", "Node", "NodeKind", "generate_layout"]

NodeKind = Literal["junction", "end", "drawpoint", "dump"]
EdgeKind = Literal["drive", "production", "drawpoint", "dump", "access"]


@dataclass(frozen=True)
class Node:
    """A junction or a dead end of the centreline graph; ``xy`` in mine-grid metres."""

    id: int
    xy: tuple[float, float]
    kind: NodeKind
    name: str


@dataclass(frozen=True, eq=False)
class Edge:
    """A tunnel between two nodes; ``polyline`` is ``(N, 2)`` grid metres running from ``a`` to ``b``."""

    id: int
    a: int
    b: int
    polyline: FloatArray
    kind: EdgeKind
    width_m: float

    @property
    def length_m(self) -> float:
        return polyline_length(self.polyline)


@dataclass(frozen=True, eq=False)
class Layout:
    """A generated level: the centreline graph, the tunnel outline and its wall rings (grid metres)."""

    seed: int
    size: str
    nodes: tuple[Node, ...]
    edges: tuple[Edge, ...]
    height_m: float
    outline: Polygon  # union of the tunnel footprints
    walls: tuple[FloatArray, ...]  # closed rings (first point repeated last), exterior first

    @property
    def total_length_m(self) -> float:
        """Total centreline length in metres."""
        return float(sum(e.length_m for e in self.edges))

    def incident(self, node: int) -> list[tuple[Edge, int]]:
        """Edges at ``node`` with the node at their other end (an edge twice for a self-loop)."""
        out: list[tuple[Edge, int]] = []
        for e in self.edges:
            if e.a == node:
                out.append((e, e.b))
            if e.b == node:
                out.append((e, e.a))
        return out

    def degree(self, node: int) -> int:
        return len(self.incident(node))

    def cycle_rank(self) -> int:
        """Independent cycles of the centreline graph: edges - nodes + connected components."""
        parent = list(range(len(self.nodes)))

        def find(i: int) -> int:
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        for e in self.edges:
            parent[find(e.a)] = find(e.b)
        components = len({find(i) for i in range(len(self.nodes))})
        return len(self.edges) - len(self.nodes) + components

    def nodes_of_kind(self, kind: NodeKind) -> list[Node]:
        return [n for n in self.nodes if n.kind == kind]


# ------------------------------------------------------------------------------------------- generation


@dataclass
class _Tunnel:
    """A tunnel under construction in the local frame: polyline plus attachment points along it."""

    poly: FloatArray
    kind: EdgeKind
    width_m: float
    closed: bool = False
    attach: list[tuple[float, int]] | None = None  # (arc length, node id) of junctions along it


def _bendy(a: FloatArray, b: FloatArray, bend_m: float, rng: np.random.Generator) -> FloatArray:
    """A polyline from a to b with interior vertices every ~30 m jittered sideways by up to bend_m."""
    length = float(np.hypot(*(b - a)))
    n = max(round(length / 30.0), 1)
    t = np.linspace(0.0, 1.0, n + 1)
    pts = a + t[:, None] * (b - a)
    normal = np.array([-(b - a)[1], (b - a)[0]]) / max(length, 1e-9)
    jitter = rng.uniform(-bend_m, bend_m, n + 1)
    jitter[0] = jitter[-1] = 0.0
    return pts + jitter[:, None] * normal


def generate_layout(seed: int, size: SiteSize) -> Layout:
    """Generate the level of ``size`` for ``seed``: same inputs, same layout.

    Args:
        seed: the site seed.
        size: the site size (layout parameters).

    Returns:
        The layout in mine-grid metres (x east ~10-20 km, y north ~50-60 km), randomly rotated.
    """
    p: LayoutParams = size.layout
    rng = np.random.default_rng([seed, 11])
    level = _Level(p, rng)
    production = level.production_tunnels()
    level.drawpoints(production)
    loop, sides = level.loop.poly, level.sides
    west_mid = polyline_length(loop) - 0.5 * polyline_length(sides[3])
    level.spur(
        level.loop, west_mid, -1, _Spur("dump", "dump", "DUMP", p.dump_length_m, p.drawpoint_width_m, 80.0)
    )
    if p.access_length_m > 0:
        east_mid = polyline_length(sides[0]) + 0.5 * polyline_length(sides[1])
        access = _Spur("access", "end", "ACCESS", p.access_length_m, p.drive_width_m, 90.0)
        level.spur(level.loop, east_mid, -1, access)
    # to the mine grid: rotate about the local origin and translate
    angle = rng.uniform(0.0, 2.0 * math.pi)
    origin = np.array([rng.uniform(11_000.0, 17_000.0), rng.uniform(51_000.0, 57_000.0)]).round(2)
    rot = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])

    def to_grid(xy: FloatArray) -> FloatArray:
        return np.asarray(xy @ rot.T + origin, dtype=np.float64)

    out_nodes, out_edges = _build_graph(level.tunnels, level.nodes, to_grid)
    outline = _outline(out_nodes, out_edges)
    rings = [np.asarray(outline.exterior.coords), *(np.asarray(r.coords) for r in outline.interiors)]
    return Layout(seed, size.name, tuple(out_nodes), tuple(out_edges), p.height_m, outline, tuple(rings))


@dataclass(frozen=True)
class _Spur:
    """A dead-end side drive: what it is, how long and wide, and its slant off the host tunnel."""

    kind: EdgeKind
    end_kind: NodeKind
    name: str
    length_m: float
    width_m: float
    slant_deg: float  # from the direction of the face walk that enters it (see the module docstring)


class _Level:
    """A level under construction in a local frame (metres, loop's south-west corner near 0, 0)."""

    def __init__(self, p: LayoutParams, rng: np.random.Generator) -> None:
        self.p, self.rng = p, rng
        L, D = p.loop_length_m, p.loop_depth_m
        corners = [
            np.array(c, dtype=np.float64) + rng.uniform(-1.5, 1.5, 2)
            for c in ((0, 0), (L, 0), (L, D), (0, D))
        ]
        self.sides = [_bendy(corners[i], corners[(i + 1) % 4], p.bend_m, rng) for i in range(4)]
        ring = np.concatenate([self.sides[0], *(s[1:] for s in self.sides[1:])])  # closed, counter-clockwise
        self.loop = _Tunnel(ring, "drive", p.drive_width_m, closed=True, attach=[])
        self.tunnels: list[_Tunnel] = [self.loop]
        self.nodes: list[tuple[FloatArray, NodeKind, str]] = []
        self.drawpoint_count = 0

    def add_node(self, xy: FloatArray, kind: NodeKind, name: str) -> int:
        self.nodes.append((np.asarray(xy, dtype=np.float64), kind, name))
        return len(self.nodes) - 1

    def attach(self, t: _Tunnel, s_m: float) -> int:
        """A junction on tunnel t at arc length s_m."""
        node = self.add_node(point_at(t.poly, s_m), "junction", "")
        assert t.attach is not None
        t.attach.append((s_m, node))
        return node

    def spur(self, t: _Tunnel, s_m: float, side: int, spec: _Spur) -> None:
        """A spur off tunnel t at arc s_m; side +1 = left of t's direction (slanting forward along it),
        -1 = right (slanting backward along t, i.e. forward for the face walked the other way)."""
        j = self.attach(t, s_m)
        slant = math.radians(spec.slant_deg)
        theta = heading_at(t.poly, s_m) + (slant if side > 0 else slant - math.pi)
        start = self.nodes[j][0]
        end = start + spec.length_m * np.array([math.cos(theta), math.sin(theta)])
        leaf = self.add_node(end, spec.end_kind, spec.name)
        attach = [(0.0, j), (spec.length_m, leaf)]
        self.tunnels.append(_Tunnel(np.stack([start, end]), spec.kind, spec.width_m, attach=attach))

    def production_tunnels(self) -> list[_Tunnel]:
        """Straight cross-cuts from the loop's south side to its north side."""
        p, loop = self.p, self.loop.poly
        south, north = self.sides[0], self.sides[2][::-1]
        out = []
        for i in range(1, p.rungs + 1):
            x = p.loop_length_m * i / (p.rungs + 1) + self.rng.uniform(-3.0, 3.0)
            a = np.array([x, np.interp(x, south[:, 0], south[:, 1])])
            b = np.array([x, np.interp(x, north[:, 0], north[:, 1])])
            ja, jb = self.attach(self.loop, project(loop, a)[0]), self.attach(self.loop, project(loop, b)[0])
            poly = np.stack([self.nodes[ja][0], self.nodes[jb][0]])
            attach = [(0.0, ja), (polyline_length(poly), jb)]
            rung = _Tunnel(poly, "production", p.production_width_m, attach=attach)
            self.tunnels.append(rung)
            out.append(rung)
        return out

    def drawpoints(self, production: list[_Tunnel]) -> None:
        """Herringbone drawpoints along each production tunnel (on the loop's north side if none)."""
        p = self.p
        for host in production or [self.loop]:
            if host.closed:
                s_lo = polyline_length(self.sides[0]) + polyline_length(self.sides[1]) + 10.0
                s_hi = s_lo + polyline_length(self.sides[2]) - 20.0
            else:
                s_lo, s_hi = 12.0, polyline_length(host.poly) - 14.0
            count = int(np.floor(max(s_hi - s_lo, 0.0) / p.drawpoint_spacing_m + 0.25)) + 1
            positions = np.linspace(s_lo, s_hi, count) if count > 1 else np.array([s_lo])
            for k, s in enumerate(positions):
                self.drawpoint_count += 1
                side = -1 if host.closed else (1 if k % 2 == 0 else -1)
                name = f"DP{self.drawpoint_count:02d}"
                self.spur(
                    host,
                    float(s),
                    side,
                    _Spur("drawpoint", "drawpoint", name, p.drawpoint_length_m, p.drawpoint_width_m, 60.0),
                )


def _build_graph(
    tunnels: list[_Tunnel],
    nodes: list[tuple[FloatArray, NodeKind, str]],
    to_grid: Callable[[FloatArray], FloatArray],
) -> tuple[list[Node], list[Edge]]:
    """Split every tunnel at its attachment points into edges; name the junctions J1, J2, ..."""
    edges: list[Edge] = []
    for t in tunnels:
        att = sorted(t.attach or [])
        if t.closed:
            # rotate the ring so it starts at the first junction, then split at the others
            s0 = att[0][0]
            ring = np.concatenate([split_at(t.poly, [s0])[1], split_at(t.poly, [s0])[0][1:]])
            cuts = [s - s0 for s, _ in att[1:]]
            pieces = split_at(ring, cuts)
            ends = [n for _, n in att] + [att[0][1]]
        else:
            pieces = split_at(t.poly, [s for s, _ in att[1:-1]])
            ends = [n for _, n in att]
        for i, piece in enumerate(pieces):
            edges.append(Edge(len(edges), ends[i], ends[i + 1], to_grid(piece), t.kind, t.width_m))
    names: list[str] = []
    j = 0
    for _, kind, name in nodes:
        if kind == "junction":
            j += 1
            name = f"J{j}"
        names.append(name)
    out_nodes = [
        Node(i, (float(g[0]), float(g[1])), kind, names[i])
        for i, ((xy, kind, _), g) in enumerate(zip(nodes, (to_grid(xy) for xy, _, _ in nodes), strict=True))
    ]
    return out_nodes, edges


def _outline(nodes: list[Node], edges: list[Edge]) -> Polygon:
    """Union of flat-capped tunnel footprints plus a disc at every junction; simplified to 2 cm."""
    parts = [
        LineString(e.polyline).buffer(e.width_m / 2, cap_style="flat", join_style="round", quad_segs=4)
        for e in edges
    ]
    for n in nodes:
        if n.kind == "junction":
            widest = max(e.width_m for e in edges if n.id in (e.a, e.b))
            parts.append(Point(n.xy).buffer(widest / 2 + 0.3, quad_segs=6))
    union = shapely.unary_union(parts).simplify(0.02)
    if not isinstance(union, Polygon):
        raise RuntimeError("tunnel footprints do not form one connected outline")
    return shapely.geometry.polygon.orient(union, sign=1.0)
