"""Map compression (paper III-A-4): the optimised mapping drives of a site become a graph of places.

Input: every mapping drive's optimised trajectory, planar poses sTv = [x_m, y_m, yaw_rad] in the survey
frame (x east, y north, yaw counter-clockwise from +x: the way the vehicle faces). Output: a
:class:`~driftmap.core.topomap.model.TopoMap`
with a node every N metres of tunnel, each holding the frames that saw it, the connectivity graph and the
sparse shortest-path matrix A that the HMM localiser (III-B) turns into its transition matrix.

Nodes and edges come from :func:`driftmap.core.topomap.adjacency.trace_nodes`, whose docstring states the rules
(stand still, join, the wall rule, create, near misses, break). Afterwards each node's centre becomes the
mean over its visits (a visit: one drive passing once) of the pose nearest its build-time centre, so a long
stop counts once; every pose outside its traced node's area goes to the nearest of that node and its graph
neighbours (so poses between node areas go to the nearer of the nodes before and after them, never across a
wall); and each node keeps at most ``frames_per_node`` frames chosen by a pluggable :data:`~driftmap.core.topomap.model.FrameSelector`
(default: distinct headings first, so both travel directions, then distinct drives, then nearest the centre
and best quality). SESAME's BuildSalientDatabase ([SESAME], Algorithm 1) plugs in there: it receives every
member frame of a node with positions, headings, distances and qualities. A node that a drive stepped over
(a frame step longer than N) holds no frame; it still carries the connectivity.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from functools import partial
from typing import Any

import numpy as np
from numpy.typing import NDArray

from driftmap.core.topomap import adjacency
from driftmap.core.topomap.distances import shortest_paths
from driftmap.core.topomap.model import (
    TOPOMAP_DEFAULT,
    FrameSelector,
    NodeFrames,
    TopoMap,
    TopoMapParams,
    per_node,
    select_frames_by_heading,
)
from driftmap.core.types import F64, I64
from driftmap.errors import BadInputError

__all__ = ["build_topomap"]


def _check_inputs(
    poses_sTv: Sequence[F64],
    frame_ids: Sequence[NDArray[np.integer]] | None,
    quality: Sequence[NDArray[np.floating]] | None,
) -> tuple[list[F64], list[I64], list[F64]]:
    poses, ids, qual = [], [], []
    for c, pose in enumerate(poses_sTv):
        pose = np.asarray(pose, dtype=np.float64)
        if pose.ndim != 2 or pose.shape[1] != 3 or not np.isfinite(pose).all():
            raise BadInputError(f"chain {c}: poses must be finite (N, 3) [x, y, yaw]", field="poses_sTv")
        n = pose.shape[0]
        fid = np.arange(n, dtype=np.int64) if frame_ids is None else np.asarray(frame_ids[c])
        q = np.zeros(n) if quality is None else np.asarray(quality[c], dtype=np.float64)
        if fid.shape != (n,) or (n and not np.issubdtype(fid.dtype, np.integer)):
            raise BadInputError(f"chain {c}: needs one integer id per pose", field="frame_ids")
        if q.shape != (n,) or not np.isfinite(q).all():
            raise BadInputError(f"chain {c}: needs one finite quality per pose", field="quality")
        poses.append(pose)
        ids.append(fid.astype(np.int64))
        qual.append(q)
    if frame_ids is not None and len(frame_ids) != len(poses):
        raise BadInputError("one frame id array per chain is required", field="frame_ids")
    if quality is not None and len(quality) != len(poses):
        raise BadInputError("one quality array per chain is required", field="quality")
    return poses, ids, qual


def _runs(*labels: I64) -> I64:
    """(F,) int64 run number of each row: a run is a stretch of consecutive rows with equal labels."""
    change = np.zeros(labels[0].shape[0], dtype=bool)
    change[:1] = True
    for lab in labels:
        change[1:] |= lab[1:] != lab[:-1]
    return np.cumsum(change).astype(np.int64) - 1


def _first_per_run(run: I64, key: F64) -> I64:
    """(R,) int64 row with the least ``key`` in each run, in run order."""
    order = np.lexsort((key, run))
    return order[np.r_[True, run[order][1:] != run[order][:-1]]] if run.size else run


def _visit_centres(build_m: F64, xy_m: F64, node: I64, near: NDArray[np.bool_], chain: I64) -> F64:
    """(M, 2) centres: the mean over visits of each visit's pose nearest the build-time centre."""
    dist = np.where(near, np.linalg.norm(xy_m - build_m[node], axis=1), np.inf)
    best = _first_per_run(_runs(chain, node), dist)
    best = best[np.isfinite(dist[best])]
    count = np.bincount(node[best], minlength=build_m.shape[0]).astype(np.float64)
    total = np.stack(
        [np.bincount(node[best], xy_m[best, k], minlength=build_m.shape[0]) for k in (0, 1)], axis=1
    )
    return np.where(count[:, None] > 0, total / np.maximum(count, 1.0)[:, None], build_m)


def _nearest_of_neighbours(centres_m: F64, edges: I64, xy_m: F64, node: I64) -> I64:
    """(F,) int64: each pose goes to the nearest of its traced node and that node's graph neighbours."""
    m = centres_m.shape[0]
    if edges.size == 0:
        return node
    src = np.r_[edges[:, 0], edges[:, 1]]
    dst = np.r_[edges[:, 1], edges[:, 0]]
    order = np.argsort(src, kind="stable")
    src, dst = src[order], dst[order]
    slot = np.arange(src.size) - np.searchsorted(src, src)
    table = np.tile(np.arange(m, dtype=np.int64)[:, None], (1, int(slot.max()) + 2))
    table[src, slot + 1] = dst  # column 0: the node itself; unused slots repeat it
    cands = table[node]
    dist = np.linalg.norm(xy_m[:, None, :] - centres_m[cands], axis=2)
    return np.asarray(cands[np.arange(node.size), np.argmin(dist, axis=1)], dtype=np.int64)


def _heading_sets(node_v: I64, yaw_v: F64, n_nodes: int, tol_rad: float) -> tuple[I64, F64]:
    """Ragged (ptr, headings) of each node: visit headings grouped within ``tol_rad``, circular means."""
    order = np.argsort(node_v, kind="stable")
    ptr = np.r_[0, np.cumsum(np.bincount(node_v, minlength=n_nodes))].astype(np.int64)
    out_ptr, out = [0], list[float]()
    for i in range(n_nodes):
        groups: list[list[float]] = []
        for yaw in yaw_v[order[ptr[i] : ptr[i + 1]]].tolist():
            near = [g for g in groups if abs((yaw - g[0] + math.pi) % math.tau - math.pi) < tol_rad]
            if near:
                near[0].append(yaw)
            else:
                groups.append([yaw])
        out.extend(math.atan2(sum(map(math.sin, g)), sum(map(math.cos, g))) for g in groups)
        out_ptr.append(len(out))
    return np.asarray(out_ptr, dtype=np.int64), np.asarray(out, dtype=np.float64)


def build_topomap(
    poses_sTv: Sequence[F64],
    frame_ids: Sequence[NDArray[np.integer]] | None = None,
    quality: Sequence[NDArray[np.floating]] | None = None,
    params: TopoMapParams = TOPOMAP_DEFAULT,
    select_frames: FrameSelector | None = None,
) -> TopoMap:
    """Compress the optimised mapping drives of a site into the stored map (paper III-A-4).

    Args:
        poses_sTv: per chain (drive), (N_i, 3) float64 optimised poses [x_m, y_m, yaw_rad] in time order:
            survey-from-vehicle, x east, y north, yaw counter-clockwise from +x, the vehicle heading.
        frame_ids: per chain, (N_i,) integer frame identifiers; default 0..N_i-1.
        quality: per chain, (N_i,) float64 frame quality weights (larger is better, typically in [0, 1])
            used when choosing frames; default none.
        params: compression parameters.
        select_frames: chooses each node's frames (e.g. SESAME's BuildSalientDatabase); default
            :func:`select_frames_by_heading` with the heading tolerance and quality gain of ``params``.

    Returns:
        The map; frames are addressed by their flat index over the chains in input order.
    """
    poses, ids, qual = _check_inputs(poses_sTv, frame_ids, quality)
    p = params
    limits = (p.spacing_m, p.merge_radius_m, p.wall_detour_m, p.stationary_tol_m, p.max_frame_step_m)
    trace = adjacency.trace_nodes([pose[:, :2] for pose in poses], *limits)
    counts = [pose.shape[0] for pose in poses]
    chain_ptr = np.r_[0, np.cumsum(counts)].astype(np.int64)
    allp = np.concatenate([np.empty((0, 3)), *poses])
    xy, yaw = allp[:, :2], allp[:, 2]
    chain = np.repeat(np.arange(len(poses), dtype=np.int64), counts)
    near = np.concatenate([np.empty(0, dtype=bool), *trace.near])
    traced = np.concatenate([chain[:0], *trace.node])
    centres = _visit_centres(trace.centres_m, xy, traced, near, chain)
    node = np.where(near, traced, _nearest_of_neighbours(centres, trace.edges, xy, traced))
    dist = np.linalg.norm(xy - centres[node], axis=1)
    visit = _runs(chain, node)
    m = centres.shape[0]

    tol, gain = p.heading_tolerance_rad, p.quality_gain_m
    select = select_frames or per_node(
        partial(select_frames_by_heading, heading_tolerance_rad=tol, quality_gain_m=gain)
    )
    qual_all = np.concatenate([np.empty(0), *qual])
    ids_all = np.concatenate([chain[:0], *ids])
    order = np.argsort(node, kind="stable")
    ptr = np.r_[0, np.cumsum(np.bincount(node, minlength=m))].astype(np.int64)
    row = np.arange(chain.size) - chain_ptr[chain]
    per_frame: tuple[NDArray[Any], ...] = (chain, row, ids_all, xy, yaw, dist, qual_all, visit)
    seen = [i for i in range(m) if ptr[i + 1] > ptr[i]]  # a drive may step over a node: no frame saw it
    members = [order[ptr[i] : ptr[i + 1]] for i in seen]
    picks = select(
        [
            NodeFrames(i, centres[i], *(a[rows] for a in per_frame))
            for i, rows in zip(seen, members, strict=True)
        ],
        p.frames_per_node,
    )
    if len(picks) != len(seen):
        raise BadInputError(
            f"frame selector answered {len(picks)} of {len(seen)} nodes", field="select_frames"
        )
    chosen_per_node = [np.zeros(0, dtype=np.int64) for _ in range(m)]
    for i, rows, pick in zip(seen, members, map(np.asarray, picks), strict=True):
        bad = pick.ndim != 1 or pick.size > p.frames_per_node or np.unique(pick).size != pick.size
        bad = bad or (pick.size > 0 and pick.dtype.kind not in "iu")
        if bad or (pick.size and (pick.min() < 0 or pick.max() >= rows.size)):
            raise BadInputError(f"frame selector returned {pick} for node {i}", field="select_frames")
        chosen_per_node[i] = rows[pick]
    chosen_ptr = np.r_[0, np.cumsum([c.size for c in chosen_per_node])].astype(np.int64)
    chosen = np.concatenate([np.zeros(0, dtype=np.int64), *chosen_per_node])

    closest = _first_per_run(visit, dist)
    heading_ptr, headings = _heading_sets(node[closest], yaw[closest], m, p.heading_tolerance_rad)
    edges = trace.edges
    lengths = np.linalg.norm(centres[edges[:, 0]] - centres[edges[:, 1]], axis=1)
    return TopoMap(
        params=p,
        centres_m=centres,
        chain_ptr=chain_ptr,
        frame_ids=ids_all,
        frame_node=node,
        frame_dist_m=dist,
        chosen_ptr=chosen_ptr,
        chosen=chosen.astype(np.int64),
        heading_ptr=heading_ptr,
        headings_rad=headings,
        edges=edges,
        edge_length_m=lengths,
        adjacency_m=shortest_paths(m, edges, lengths, p.max_adjacency_m),
    )
