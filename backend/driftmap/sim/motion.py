"""Vehicle motion of the drives: mapping drives along graph faces, LHD duty cycles for localisation.

Mapping (:func:`plan_mapping`): one drive per face of the planar centreline graph (see
:mod:`driftmap.sim.routes`), so that together they drive every tunnel once in each direction. The
vehicle stops for a surveyor's grounding at its start and end, at every dead end (tunnel ends, the
dump, drawpoints) and at each main junction the first time a mapping drive passes it; at drawpoints
it also digs (short back-and-forth strokes) before reversing out.

Localisation (:func:`plan_localisation`): load-haul-dump cycles -- reverse out of the dump, drive
empty (up to 7 m/s) to a drawpoint, dig, reverse out, haul loaded to the dump, tip, and again --
with traffic waits at junctions, until the drive's frame share is used.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from driftmap.sim.geometry import FloatArray, point_at, sub_polyline
from driftmap.sim.params import VehicleParams
from driftmap.sim.routes import Dart, Graph
from driftmap.sim.trajectory import Run, Stop, TimedRun, time_run

__all__ = ["DrivePlan", "plan_localisation", "plan_mapping"]


@dataclass(frozen=True, eq=False)
class DrivePlan:
    """One drive's timed runs; the vehicle stands still for ``start_dwell_s`` before the first."""

    name: str
    kind: Literal["mapping", "localisation"]
    runs: tuple[TimedRun, ...]
    start_dwell_s: float
    start_grounding: bool  # a grounding in the middle of the initial pause
    darts: tuple[Dart, ...] = ()  # darts driven forward (for coverage checks)

    @property
    def duration_s(self) -> float:
        return self.start_dwell_s + sum(r.duration_s for r in self.runs)

    def frame_count(self, fps: float) -> int:
        return int(np.floor(self.duration_s * fps + 1e-9)) + 1


def _xy(p: FloatArray | tuple[float, float]) -> tuple[float, float]:
    return float(p[0]), float(p[1])


def _join(pieces: list[FloatArray]) -> FloatArray:
    pts = np.concatenate(pieces)
    keep = np.concatenate([[True], np.hypot(*np.diff(pts, axis=0).T) > 1e-6])
    return np.asarray(pts[keep])


@dataclass
class _Builder:
    """Accumulates the runs of one drive."""

    g: Graph
    vp: VehicleParams
    y_c_m: float
    rng: np.random.Generator
    runs: list[TimedRun] = field(default_factory=list)
    pieces: list[FloatArray] = field(default_factory=list)
    stops: list[Stop] = field(default_factory=list)
    darts: list[Dart] = field(default_factory=list)

    def _time(self, run: Run) -> None:
        self.runs.append(time_run(run, self.vp))

    def _seed(self) -> int:
        return int(self.rng.integers(0, 2**31))

    def rear_end(self, d: Dart) -> float:
        """Arc length along a dead-end dart where the rear axle stops (camera ``standoff`` from the face)."""
        return max(self.g.length(d) - self.vp.deadend_standoff_m - self.y_c_m, 1.0)

    def forward(self, d: Dart, stop_at_head: Stop | None = None) -> None:
        self.pieces.append(self.g.poly(d))
        self.darts.append(d)
        if stop_at_head is not None:
            self.stops.append(stop_at_head)

    def finish_forward(self, speed: float, end: Stop | None, into_leaf: Dart | None = None) -> None:
        """Drive the accumulated path; with ``into_leaf`` the path ends at that dead end's stop point."""
        if into_leaf is not None:
            self.pieces.append(sub_polyline(self.g.poly(into_leaf), 0.0, self.rear_end(into_leaf)))
            self.darts.append(into_leaf)
        if self.pieces:
            run = Run(_join(self.pieces), False, speed, tuple(self.stops), end, True, self._seed())
            self._time(run)
        self.pieces, self.stops = [], []

    def dig(self, into_leaf: Dart, strokes: int) -> None:
        """Bucket-filling strokes at a drawpoint face: reverse a little, push in again, pause."""
        poly = self.g.poly(into_leaf)
        a = point_at(poly, self.rear_end(into_leaf))
        back = point_at(poly, self.rear_end(into_leaf) - self.vp.dig_stroke_m)
        for _ in range(strokes):
            self._time(Run(np.stack([a, back]), True, 1.0, (), Stop(_xy(back), 0.6), False))
            pause = Stop(_xy(a), float(self.rng.uniform(*self.vp.dig_s)), "dig")
            self._time(Run(np.stack([back, a]), False, 1.0, (), pause, False))

    def reverse_out(self, into_leaf: Dart, e_r: Dart) -> None:
        """Reverse out of the dead end into ``e_r``; the next forward path starts at the cusp."""
        out = sub_polyline(self.g.poly(into_leaf), 0.0, self.rear_end(into_leaf))[::-1]
        swing = sub_polyline(self.g.poly(e_r), 0.0, self.vp.reverse_into_m)
        run = Run(_join([out, swing]), True, self.vp.reverse_speed_mps, (), Stop(_xy(swing[-1]), 1.0), False)
        self._time(run)
        self.pieces = [swing[::-1]]


def plan_mapping(g: Graph, vp: VehicleParams, y_c_m: float, seed: int) -> list[DrivePlan]:
    """One mapping drive per face walk of the centreline graph, named ``map-01``, ``map-02``, ...

    Args:
        g: the layout's dart graph.
        vp: vehicle parameters.
        y_c_m: camera ahead of the rear axle.
        seed: site seed.
    """
    plans = []
    nodes = g.layout.nodes
    grounded: set[int] = set()  # main junctions already grounded by an earlier drive
    for k, walk in enumerate(g.faces()):
        starts = [i for i, d in enumerate(walk) if g.main_junction(g.tail(d))]
        starts = starts or [i for i, d in enumerate(walk) if nodes[g.tail(d)].kind == "junction"] or [0]
        walk = walk[starts[0] :] + walk[: starts[0]]
        b = _Builder(g, vp, y_c_m, np.random.default_rng([seed, 31, k]))
        surveyor = _Surveyor(g, vp, grounded)
        if not _leave_base(g, b, walk[0], surveyor):
            surveyor.start_at(g.tail(walk[0]))
        i, n = 0, len(walk)
        while i < n:
            d = walk[i]
            head = g.head(d)
            if g.is_leaf(head):
                node = nodes[head]
                b.finish_forward(vp.mapping_speed_mps, surveyor.at_leaf(head), d)
                if node.kind == "drawpoint":
                    b.dig(d, vp.mapping_dig_strokes)
                e_f = walk[(i + 2) % n]
                pair = g.reverse_out(d, e_f)
                assert pair is not None
                b.reverse_out(d, pair[0])
                i += 2
                continue
            b.forward(d, surveyor.at_junction(head) if i < n - 1 else None)
            i += 1
        b.finish_forward(vp.mapping_speed_mps, surveyor.at_leaf(g.tail(walk[0])))
        plans.append(DrivePlan(f"map-{k + 1:02d}", "mapping", tuple(b.runs), vp.stop_s, True, tuple(b.darts)))
    return plans


@dataclass
class _Surveyor:
    """Where a mapping drive stops for a grounding (one per drive; ``grounded`` is shared by all drives).

    Dead ends and the drive's start and end are always grounded. A main junction is grounded the first
    time any drive passes it; any junction is grounded when this drive's groundings so far lie within
    ``SPREAD_M`` of each other: groundings at one spot fix a drive's position but not its heading, so a
    surveyor grounds a second, distant point.
    """

    SPREAD_M = 10.0

    g: Graph
    vp: VehicleParams
    grounded: set[int]
    mine: list[tuple[float, float]] = field(default_factory=list)

    def start_at(self, node: int) -> None:
        """The drive starts (with its start grounding) at ``node``."""
        self.mine.append(_xy(self.g.layout.nodes[node].xy))
        self.grounded.add(node)

    def at_leaf(self, node: int) -> Stop:
        """The grounding stop at a dead end or at the drive's end."""
        xy = _xy(self.g.layout.nodes[node].xy)
        self.mine.append(xy)
        return Stop(xy, self.vp.stop_s, self.g.layout.nodes[node].name, True)

    def at_junction(self, node: int) -> Stop | None:
        """A grounding stop at ``node`` when it is a main junction that needs one, else None."""
        xy = _xy(self.g.layout.nodes[node].xy)
        far = all(np.hypot(xy[0] - m[0], xy[1] - m[1]) >= self.SPREAD_M for m in self.mine)
        clustered = all(
            np.hypot(a[0] - c[0], a[1] - c[1]) < self.SPREAD_M for a in self.mine for c in self.mine
        )
        needs_spread = clustered and far and len(self.g.out[node]) >= 3
        if not needs_spread and (not self.g.main_junction(node) or node in self.grounded):
            return None
        self.grounded.add(node)
        self.mine.append(xy)
        return Stop(xy, self.vp.stop_s, self.g.layout.nodes[node].name, True)


def _leave_base(g: Graph, b: _Builder, first: Dart, surveyor: _Surveyor) -> bool:
    """Start the drive parked at the dump and drive to the tail of ``first``; False if there is no route.

    Every mapping drive leaves from the same base, as a real survey vehicle leaves its parking bay, so the
    access tunnels are driven again in the same direction by later drives: loop closures tie the drives
    together there.
    """
    dumps = _leaf_darts(g, "dump")
    plan = g.plan_from_leaf(dumps[0], first) if dumps and g.tail(first) != g.tail(dumps[0]) else None
    if plan is None:
        return False
    e_r, access = plan
    surveyor.start_at(g.head(dumps[0]))
    b.reverse_out(dumps[0], e_r)
    for d in access[:-1]:
        b.forward(d, surveyor.at_junction(g.head(d)))
    return True


def _leaf_darts(g: Graph, kind: str) -> list[Dart]:
    return sorted(d for ds in g.out.values() for d in ds if g.layout.nodes[g.head(d)].kind == kind)


def plan_localisation(
    g: Graph, vp: VehicleParams, y_c_m: float, seed: int, index: int, target_frames: int
) -> DrivePlan:
    """A localisation drive of LHD cycles between drawpoints and the dump, about ``target_frames`` long.

    Args:
        g: the layout's dart graph.
        vp: vehicle parameters.
        y_c_m: camera ahead of the rear axle.
        seed: site seed.
        index: 0-based drive number (odd drives start loaded at a drawpoint, even ones at the dump).
        target_frames: the drive ends after the leg (drive to a drawpoint and dig, or to the dump and
            tip) that brings it closest to this many frames; it has at least one leg.
    """
    rng = np.random.default_rng([seed, 41, index])
    dump = _leaf_darts(g, "dump")[0]
    drawpoints = _leaf_darts(g, "drawpoint")
    b = _Builder(g, vp, y_c_m, rng)
    current = dump if index % 2 == 0 or not drawpoints else drawpoints[int(rng.integers(len(drawpoints)))]
    start_dwell = 1.5
    nodes = g.layout.nodes
    legs = 0
    while True:
        before = (len(b.runs), len(b.darts), start_dwell + sum(r.duration_s for r in b.runs))
        order = [drawpoints[int(j)] for j in rng.permutation(len(drawpoints))] if current == dump else [dump]
        plan = None
        for goal in order:
            plan = g.plan_from_leaf(current, goal)
            if plan is not None:
                break
        if plan is None:
            raise RuntimeError(f"no route out of {nodes[g.head(current)].name}")
        e_r, darts = plan
        goal = darts[-1]
        b.reverse_out(current, e_r)
        for d in darts[:-1]:
            head = g.head(d)
            wait = None
            if g.main_junction(head) and rng.random() < vp.wait_probability:
                wait = Stop(_xy(nodes[head].xy), float(rng.uniform(*vp.wait_s)), "wait")
            b.forward(d, wait)
        loaded = goal == dump
        speed = vp.loaded_speed_mps if loaded else vp.empty_speed_mps
        target = nodes[g.head(goal)]
        b.finish_forward(speed, Stop(_xy(target.xy), vp.tip_s if loaded else 1.5, target.name), goal)
        if not loaded:
            b.dig(goal, vp.dig_strokes)
        current = goal
        legs += 1
        frames = (start_dwell + sum(r.duration_s for r in b.runs)) * vp.fps
        if frames >= target_frames:
            if legs > 1 and frames - target_frames > target_frames - before[2] * vp.fps:
                del b.runs[before[0] :], b.darts[before[1] :]  # closer to the target without this leg
            break
    return DrivePlan(
        f"loc-{index + 1:02d}", "localisation", tuple(b.runs), start_dwell, False, tuple(b.darts)
    )
