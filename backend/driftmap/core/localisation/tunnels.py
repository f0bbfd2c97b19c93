"""Keeping a localising vehicle's track on the mapped tunnels (beyond [SSLAM]).

The continuous track (:mod:`driftmap.core.localisation.track`) is dead-reckoned and corrected by place fixes;
this module puts it back on the nearest mapped edge beside it (a segment of the mapped paths, or of the edges
between node centres) and pulls its heading towards that edge's direction while the vehicle drives straight.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from driftmap.core.localisation.track import TrackParams, TrackState, wrap_angle
from driftmap.core.topomap.model import wrap_rad
from driftmap.core.types import F64, I64

__all__ = ["snap"]


def _axial_rad(a_rad: F64 | float, b_rad: F64 | float) -> F64:
    """|a - b| between two undirected directions, radians in [0, pi/2]."""
    d = np.abs(wrap_rad(np.asarray(a_rad, dtype=np.float64) - b_rad))
    return np.asarray(np.minimum(d, np.pi - d), dtype=np.float64)


def _nearest_on_edges(
    xy: F64, centres_m: F64, edges: I64, heading_rad: float = math.nan, max_turn_rad: float = math.pi
) -> tuple[F64, float, float] | None:
    """The nearest point to ``xy`` on one of the segments ``edges`` (K, 2) of ``centres_m``
    (its foot of the perpendicular, or the vertex two of the segments share when ``xy`` lies in the wedge
    outside a bend between them), its distance and the segment's direction (radians); None when ``xy``
    lies beside no segment (past the end of every one: a dead end, or a gap in the mapped edges, where
    pulling it back to the end would stop it). With a finite ``heading_rad`` only segments whose direction
    is within ``max_turn_rad`` of it (either way along the segment) count: a vehicle driving across a
    tunnel's line (into a drawpoint or a stub the map has no edge for) is not on that tunnel."""
    if edges.size == 0:
        return None
    a, b = centres_m[edges[:, 0]], centres_m[edges[:, 1]]
    ab = b - a
    length2 = np.einsum("ij,ij->i", ab, ab)
    t = np.einsum("ij,ij->i", xy - a, ab) / np.where(length2 > 0, length2, 1.0)
    usable = length2 > 0
    if math.isfinite(heading_rad):
        usable &= _axial_rad(np.arctan2(ab[:, 1], ab[:, 0]), heading_rad) <= max_turn_rad
    ends, count = np.unique(edges[usable].ravel(), return_counts=True)
    shared = ends[count >= 2]  # a vertex joining two segments: no dead end
    inner = ((t < 0.0) & np.isin(edges[:, 0], shared)) | ((t > 1.0) & np.isin(edges[:, 1], shared))
    beside = usable & (((t >= 0.0) & (t <= 1.0)) | inner)
    if not beside.any():
        return None
    points = a + np.clip(t, 0.0, 1.0)[:, None] * ab
    dist = np.where(beside, np.hypot(*(points - xy).T), np.inf)
    k = int(np.argmin(dist))
    return points[k], float(dist[k]), math.atan2(float(ab[k, 1]), float(ab[k, 0]))


def snap(
    state: TrackState,
    centres_m: F64,
    edges: I64,
    moving: bool,
    params: TrackParams,
    steered: bool = False,
    turning: bool = False,
) -> TrackState:
    """Put the track on the nearest of the mapped ``edges`` (K, 2) int64 (node pairs, segments between
    their ``centres_m`` (M, 2)) and pull its heading towards that edge while ``moving``. A ``steered`` track
    (its heading turned by odometry this frame) goes only onto edges along its heading
    (``snap_max_turn_rad``): one driving off a mapped tunnel into a stub without edges leaves it. While
    odometry says the vehicle is ``turning`` the heading is not pulled (the pull corrects drift on the
    straight; in a turn it would take part of the turn away)."""
    if not state.has_position:
        return state
    wT = state.wT.copy()
    heading = float(wT[2]) if steered else math.nan
    found = _nearest_on_edges(wT[:2], centres_m, edges, heading, params.snap_max_turn_rad)
    edge_dir = math.nan
    if found is not None and found[1] <= params.snap_max_m:
        wT[:2], _dist, edge_dir = found
    if not np.isfinite(wT[2]) and moving and math.isfinite(edge_dir):
        wT[2] = (
            edge_dir  # one of the tunnel's two ways: check_heading or the fixes turn it if it is the other
        )
    elif np.isfinite(wT[2]) and moving and not turning and math.isfinite(edge_dir):
        err = wrap_angle(edge_dir - wT[2])
        if abs(err) > math.pi / 2:
            err = wrap_angle(err + math.pi)  # the edge's other way is nearer
        if abs(err) <= params.pull_max_rad:
            wT[2] = wrap_angle(wT[2] + params.heading_pull * err)
    return replace(state, wT=wT)
