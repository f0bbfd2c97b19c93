"""Routes through the centreline graph: darts, face walks, turn rules and shortest paths.

A dart is an edge traversed in one direction. The vehicle drives forward along darts; at a dead end
it reverses out, swinging its rear into a neighbouring tunnel ("e_r") so that it can drive forward
into another ("e_f") -- an LHD's three-point turn. Turns at junctions are limited to
``VehicleParams.turn_max_rad``.

Mapping drives follow the faces of the planar centreline graph: at every junction take the sharpest
left turn. Each face is then walked with its interior on the left, every dart belongs to exactly one
face, and every tunnel is driven once in each direction over all faces (dead ends: in forward, out in
reverse).
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

from driftmap.sim.geometry import FloatArray
from driftmap.sim.layout import Layout

__all__ = ["Dart", "Graph"]


@dataclass(frozen=True, order=True)
class Dart:
    """Edge ``edge`` traversed from its node a to b (``forward``) or from b to a."""

    edge: int
    forward: bool


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class Graph:
    """Dart geometry and turn rules of a layout."""

    def __init__(self, layout: Layout, turn_max_rad: float) -> None:
        self.layout = layout
        self.turn_max_rad = turn_max_rad
        self.out: dict[int, list[Dart]] = {n.id: [] for n in layout.nodes}
        for e in layout.edges:
            self.out[e.a].append(Dart(e.id, True))
            self.out[e.b].append(Dart(e.id, False))

    def poly(self, d: Dart) -> FloatArray:
        """The dart's centreline from its tail to its head, (N, 2) grid metres."""
        p = self.layout.edges[d.edge].polyline
        return p if d.forward else p[::-1]

    def tail(self, d: Dart) -> int:
        e = self.layout.edges[d.edge]
        return e.a if d.forward else e.b

    def head(self, d: Dart) -> int:
        e = self.layout.edges[d.edge]
        return e.b if d.forward else e.a

    def length(self, d: Dart) -> float:
        return self.layout.edges[d.edge].length_m

    def start_heading(self, d: Dart) -> float:
        p = self.poly(d)
        v = p[1] - p[0]
        return math.atan2(v[1], v[0])

    def end_heading(self, d: Dart) -> float:
        p = self.poly(d)
        v = p[-1] - p[-2]
        return math.atan2(v[1], v[0])

    def is_leaf(self, node: int) -> bool:
        return len(self.out[node]) == 1

    def turn(self, d_in: Dart, d_out: Dart) -> float:
        """Heading change (radians, left positive) from arriving on d_in to leaving on d_out."""
        return _wrap(self.start_heading(d_out) - self.end_heading(d_in))

    # ------------------------------------------------------------------------------------------ faces

    def next_in_face(self, d: Dart) -> Dart:
        """The sharpest left turn after arriving on ``d`` (a U-turn only at a dead end)."""
        outs = self.out[self.head(d)]
        if len(outs) == 1:
            return outs[0]
        back = self.end_heading(d) + math.pi
        return min(
            (o for o in outs if o.edge != d.edge),
            key=lambda o: ((back - self.start_heading(o)) % (2.0 * math.pi)) or 2.0 * math.pi,
        )

    def faces(self) -> list[list[Dart]]:
        """All face walks; together they hold every dart exactly once."""
        seen: set[Dart] = set()
        faces: list[list[Dart]] = []
        for start in sorted(d for ds in self.out.values() for d in ds):
            if start in seen:
                continue
            walk, d = [], start
            while d not in seen:
                seen.add(d)
                walk.append(d)
                d = self.next_in_face(d)
            faces.append(walk)
        return faces

    # -------------------------------------------------------------------------------- reversing out

    def reverse_out(self, into_leaf: Dart, e_f: Dart | None = None) -> tuple[Dart, Dart] | None:
        """(e_r, e_f) for reversing out of the dead end reached by ``into_leaf``.

        The rear swings into e_r (a dart leaving the junction) and the vehicle then drives forward onto
        e_f. With ``e_f`` given, picks the best e_r for it; otherwise the gentlest pair. None if no pair
        keeps both turns within the limit (or, with e_f given, the least bad e_r is returned anyway).
        """
        j = self.tail(into_leaf)
        travel_out = self.start_heading(into_leaf) + math.pi  # heading of travel leaving the dead end at j
        options = [o for o in self.out[j] if o.edge != into_leaf.edge]
        best: tuple[float, Dart, Dart] | None = None
        for f in options if e_f is None else [e_f]:
            for r in options:
                if r.edge == f.edge:
                    continue
                t_rev = abs(_wrap(self.start_heading(r) - travel_out))
                t_fwd = abs(_wrap(self.start_heading(f) - (self.start_heading(r) + math.pi)))
                bad = max(t_rev, t_fwd) > self.turn_max_rad
                cost = t_rev + t_fwd + (100.0 if bad else 0.0)
                if best is None or cost < best[0]:
                    best = (cost, r, f)
        if best is None or (e_f is None and best[0] >= 100.0):
            return None
        return best[1], best[2]

    # ------------------------------------------------------------------------------------ shortest path

    def shortest(self, starts: list[Dart], goal: Dart) -> list[Dart] | None:
        """Shortest dart sequence from one of ``starts`` to ``goal`` within the turn limit."""
        penalty = 4.0  # metres per radian of turning, prefers straight on
        dist: dict[Dart, float] = {}
        prev: dict[Dart, Dart | None] = {}
        heap: list[tuple[float, Dart]] = []
        for s in starts:
            dist[s], prev[s] = self.length(s), None
            heapq.heappush(heap, (dist[s], s))
        while heap:
            c, d = heapq.heappop(heap)
            if c > dist.get(d, math.inf):
                continue
            if d == goal:
                path: list[Dart] = []
                cur: Dart | None = d
                while cur is not None:
                    path.append(cur)
                    cur = prev[cur]
                return path[::-1]
            node = self.head(d)
            if self.is_leaf(node):
                continue
            for o in self.out[node]:
                if o.edge == d.edge:
                    continue
                t = abs(self.turn(d, o))
                if t > self.turn_max_rad:
                    continue
                nc = c + self.length(o) + penalty * t
                if nc < dist.get(o, math.inf):
                    dist[o], prev[o] = nc, d
                    heapq.heappush(heap, (nc, o))
        return None

    def plan_from_leaf(self, into_leaf: Dart, goal: Dart) -> tuple[Dart, list[Dart]] | None:
        """Reverse out of the dead end of ``into_leaf`` and drive to ``goal``: (e_r, darts from e_f)."""
        j = self.tail(into_leaf)
        pairs: dict[Dart, Dart] = {}
        for f in self.out[j]:
            if f.edge == into_leaf.edge:
                continue
            pair = self.reverse_out(into_leaf, f)
            if pair is not None:
                r = pair[0]
                t_rev = abs(_wrap(self.start_heading(r) - self.start_heading(into_leaf) - math.pi))
                t_fwd = abs(_wrap(self.start_heading(f) - self.start_heading(r) - math.pi))
                if max(t_rev, t_fwd) <= self.turn_max_rad:
                    pairs[f] = r
        path = self.shortest(sorted(pairs), goal)
        if path is None:
            return None
        return pairs[path[0]], path

    def main_junction(self, node: int) -> bool:
        """A junction of three or more tunnels other than drawpoints (where surveyors ground)."""
        kinds = [self.layout.edges[d.edge].kind for d in self.out[node]]
        return len(kinds) >= 3 and sum(k != "drawpoint" for k in kinds) >= 3
