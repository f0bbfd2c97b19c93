"""Map compression (paper III-A-4): the optimised mapping drives of a site become a graph of places.

Input: every mapping drive's optimised trajectory, planar poses sTv = [x_m, y_m, yaw_rad] in the survey
frame (x east, y north, yaw counter-clockwise from +x: the way the vehicle faces). Output: a :class:`TopoMap`
with a node every N metres of tunnel, each holding the frames that saw it, the connectivity graph and the
sparse shortest-path matrix A that the HMM localiser (III-B) turns into its transition matrix.

Nodes and edges come from :func:`driftmap.core.adjacency.trace_nodes`, whose docstring states the rules
(stand still, join, the wall rule, create, near misses, break). Afterwards each node's centre becomes the
mean over its visits (a visit: one drive passing once) of the pose nearest its build-time centre, so a long
stop counts once; every pose outside its traced node's area goes to the nearest of that node and its graph
neighbours (so poses between node areas go to the nearer of the nodes before and after them, never across a
wall); and each node keeps at most ``frames_per_node`` frames chosen by a pluggable :data:`FrameSelector`
(default: distinct headings first, so both travel directions, then distinct drives, then nearest the centre
and best quality). SESAME's BuildSalientDatabase (paper 001, Algorithm 1) plugs in there: it receives every
member frame of a node with positions, headings, distances and qualities. A node that a drive stepped over
(a frame step longer than N) holds no frame; it still carries the connectivity.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from functools import cached_property, partial
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array
from scipy.spatial import cKDTree

from driftmap.core import adjacency
from driftmap.errors import BadInputError

__all__ = ["FAST", "PAPER", "FrameSelector", "NodeFrames", "TopoMap", "TopoMapParams", "build_topomap"]

I64 = NDArray[np.int64]
F64 = NDArray[np.float64]


@dataclass(frozen=True)
class TopoMapParams:
    """Parameters of map compression; see the module docstring for the rules they drive."""

    spacing_m: float = 5.0  # N: distance along a drive between consecutive new nodes
    merge_radius_m: float = 2.5  # a pose within this of a node centre joins the node instead of making one
    frames_per_node: int = 3  # K: frames kept per node for image comparison (paper eq. 4)
    max_adjacency_m: float = 50.0  # shortest paths A(x, y) are stored up to this; longer ones are "far"
    wall_detour_m: float = 30.0  # a candidate only reachable by a detour shorter than this is behind a wall
    heading_tolerance_rad: float = math.pi / 4  # frames whose headings differ by less look the same way
    quality_gain_m: float = 1.0  # metres nearer the centre that one unit of frame quality is worth
    stationary_tol_m: float = 0.05  # a pose closer than this to the last moving pose is standing still
    max_frame_step_m: float = 10.0  # a longer jump between consecutive poses splits the drive (no edge)

    def __post_init__(self) -> None:
        for f in fields(self):
            if not getattr(self, f.name) > 0:
                raise BadInputError(f"must be positive, got {getattr(self, f.name)}", field=f.name)
        if self.merge_radius_m >= self.spacing_m:
            raise BadInputError("must be smaller than spacing_m", field="merge_radius_m")


PAPER = TopoMapParams()
FAST = TopoMapParams(spacing_m=10.0, merge_radius_m=4.0, frames_per_node=2, max_adjacency_m=40.0)


@dataclass(frozen=True)
class NodeFrames:
    """The member frames of one node as a :data:`FrameSelector` sees them; arrays have one row per frame.

    Attributes:
        node: node index.
        centre_m: (2,) float64 node centre, survey frame, metres.
        chain: (C,) int64 drive (chain) index of each frame.
        row: (C,) int64 row of each frame inside its chain.
        frame_id: (C,) int64 frame identifier as given to :func:`build_topomap`.
        xy_m: (C, 2) float64 frame positions, survey frame, metres.
        yaw_rad: (C,) float64 frame headings, radians counter-clockwise from +x.
        dist_m: (C,) float64 distance of each frame from the centre, metres.
        quality: (C,) float64 quality weight of each frame (0 when none was given), larger is better.
        visit: (C,) int64 pass label: frames of one drive passing the node once share it.
    """

    node: int
    centre_m: F64
    chain: I64
    row: I64
    frame_id: I64
    xy_m: F64
    yaw_rad: F64
    dist_m: F64
    quality: F64
    visit: I64


#: Chooses at most ``k`` of a node's frames; returns their (<= k,) int64 positions in the ``NodeFrames`` rows.
FrameSelector = Callable[[NodeFrames, int], I64]


def wrap_rad(angle_rad: F64) -> F64:
    """Angles wrapped to [-pi, pi), any shape, radians."""
    return np.asarray((angle_rad + np.pi) % (2 * np.pi) - np.pi, dtype=np.float64)


def select_frames_by_heading(
    cands: NodeFrames, k: int, heading_tolerance_rad: float = math.pi / 4, quality_gain_m: float = 1.0
) -> I64:
    """Default frame selector: one frame per visit, then distinct headings, distinct drives, nearest and best.

    Each visit offers its frame of least cost ``dist_m - quality_gain_m * quality``; frames are then taken
    greedily, preferring a heading at least ``heading_tolerance_rad`` from every frame already chosen (so
    both travel directions come first), then a drive not yet represented, then the least cost.

    Returns:
        (min(k, visits),) int64 positions into the rows of ``cands``.
    """
    cost = cands.dist_m - quality_gain_m * cands.quality
    order = np.lexsort((cands.dist_m, cost, cands.visit))
    per_visit = order[np.r_[True, cands.visit[order][1:] != cands.visit[order][:-1]]]
    rest = per_visit[np.argsort(cost[per_visit], kind="stable")]
    chosen = [int(rest[0])]
    rest = rest[1:]
    while len(chosen) < k and rest.size:
        gap = np.abs(wrap_rad(cands.yaw_rad[rest][:, None] - cands.yaw_rad[chosen][None, :])).min(axis=1)
        same_chain = (cands.chain[rest][:, None] == cands.chain[chosen][None, :]).any(axis=1)
        pick = np.lexsort((cost[rest], same_chain, gap < heading_tolerance_rad))[0]
        chosen.append(int(rest[pick]))
        rest = np.delete(rest, pick)
    return np.asarray(chosen, dtype=np.int64)


@dataclass(frozen=True, eq=False)
class TopoMap:
    """The stored map of a site: nodes every N metres, their frames, the graph and sparse distances A.

    Frames are numbered by a flat index over all chains: chain c's rows occupy ``chain_ptr[c]`` to
    ``chain_ptr[c + 1]``. Ragged per-node lists use ``*_ptr`` offsets of shape (M + 1,).

    Attributes:
        params: the parameters the map was built with.
        centres_m: (M, 2) float64 node centres, survey frame, metres.
        chain_ptr: (C + 1,) int64 offsets of the chains in the flat frame arrays.
        frame_ids: (F,) int64 identifier of every frame.
        frame_node: (F,) int64 node of every frame.
        frame_dist_m: (F,) float64 distance of every frame from its node's centre, metres.
        chosen_ptr: (M + 1,) int64 offsets into ``chosen``.
        chosen: (S,) int64 flat indices of each node's chosen frames (at most K per node).
        heading_ptr: (M + 1,) int64 offsets into ``headings_rad``.
        headings_rad: (H,) float64 representative headings of each node (one per distinct direction seen).
        edges: (E, 2) int64 node pairs ``i < j`` driven between directly.
        edge_length_m: (E,) float64 Euclidean distance between the edge's node centres, metres.
        adjacency_m: (M, M) float64 scipy csr_array, A(x, y) for x != y up to ``params.max_adjacency_m``.
    """

    params: TopoMapParams
    centres_m: F64
    chain_ptr: I64
    frame_ids: I64
    frame_node: I64
    frame_dist_m: F64
    chosen_ptr: I64
    chosen: I64
    heading_ptr: I64
    headings_rad: F64
    edges: I64
    edge_length_m: F64
    adjacency_m: csr_array

    @property
    def n_nodes(self) -> int:
        """Number of nodes M."""
        return int(self.centres_m.shape[0])

    def frame_nodes(self, chain: int) -> I64:
        """(N_chain,) int64 node of every frame of one chain, in chain order."""
        return self.frame_node[self.chain_ptr[chain] : self.chain_ptr[chain + 1]]

    def frame_refs(self, flat: I64) -> I64:
        """(n, 3) int64 rows [chain, row, frame_id] of the given (n,) flat frame indices."""
        chain = np.searchsorted(self.chain_ptr, flat, side="right") - 1
        return np.stack([chain, flat - self.chain_ptr[chain], self.frame_ids[flat]], axis=1).astype(np.int64)

    @cached_property
    def _members(self) -> tuple[I64, I64]:
        order = np.argsort(self.frame_node, kind="stable").astype(np.int64)
        ptr = np.r_[0, np.cumsum(np.bincount(self.frame_node, minlength=self.n_nodes))].astype(np.int64)
        return order, ptr

    def members(self, node: int) -> tuple[I64, F64]:
        """Frames of ``node``: (n, 3) int64 rows [chain, row, frame_id] and (n,) float64 distances, metres."""
        order, ptr = self._members
        flat = order[ptr[node] : ptr[node + 1]]
        return self.frame_refs(flat), self.frame_dist_m[flat]

    def chosen_frames(self, node: int) -> I64:
        """(<= K, 3) int64 rows [chain, row, frame_id] of the frames stored for image comparison."""
        return self.frame_refs(self.chosen[self.chosen_ptr[node] : self.chosen_ptr[node + 1]])

    def headings(self, node: int) -> F64:
        """(h,) float64 representative headings of ``node``, radians counter-clockwise from +x."""
        return self.headings_rad[self.heading_ptr[node] : self.heading_ptr[node + 1]]

    def degree(self) -> I64:
        """(M,) int64 number of graph edges at each node (>= 3 at junctions)."""
        return np.bincount(self.edges.reshape(-1), minlength=self.n_nodes).astype(np.int64)

    @cached_property
    def _tree(self) -> cKDTree:
        return cKDTree(self.centres_m)

    def nearest_nodes(self, xy_m: F64) -> tuple[I64, F64]:
        """Nearest node to each point.

        Args:
            xy_m: (P, 2) float64 points, survey frame, metres.

        Returns:
            (P,) int64 node indices and (P,) float64 distances to their centres, metres.
        """
        xy_m = np.asarray(xy_m, dtype=np.float64)
        if xy_m.ndim != 2 or xy_m.shape[1] != 2:
            raise BadInputError(f"points must have shape (P, 2), got {xy_m.shape}", field="xy_m")
        if self.n_nodes == 0:
            raise BadInputError("the map has no nodes", field="xy_m")
        dist, idx = self._tree.query(xy_m)
        return np.asarray(idx, dtype=np.int64), np.asarray(dist, dtype=np.float64)

    def nearest_node(self, x_m: float, y_m: float) -> tuple[int, float]:
        """Nearest node to one survey-frame point (metres) and its distance, metres."""
        idx, dist = self.nearest_nodes(np.array([[x_m, y_m]]))
        return int(idx[0]), float(dist[0])

    def distance_m(self, x: int, y: int) -> float:
        """A(x, y) in metres: 0 on the diagonal, ``inf`` beyond ``params.max_adjacency_m``."""
        if x == y:
            return 0.0
        lo, hi = self.adjacency_m.indptr[x], self.adjacency_m.indptr[x + 1]
        hit = np.nonzero(self.adjacency_m.indices[lo:hi] == y)[0]
        return float(self.adjacency_m.data[lo + hit[0]]) if hit.size else math.inf

    def _check_a_t(self, a_t_m: float) -> None:
        if a_t_m > self.params.max_adjacency_m:
            raise BadInputError(
                f"A_t {a_t_m} m exceeds the {self.params.max_adjacency_m} m of stored paths", field="a_t_m"
            )

    def neighbours_within(self, node: int, a_t_m: float) -> tuple[I64, F64]:
        """Nodes y with A(node, y) < a_t_m (``node`` first), and those distances in metres; see eq. 10."""
        self._check_a_t(a_t_m)
        return adjacency.neighbours_within(self.adjacency_m, node, a_t_m)

    def transition_matrix(self, a_t_m: float) -> csr_array:
        """(M, M) column-normalised HMM transition matrix of eq. 9-10 for A_t = ``a_t_m`` metres."""
        self._check_a_t(a_t_m)
        return adjacency.transition_matrix(self.adjacency_m, a_t_m)

    def to_arrays(self) -> dict[str, NDArray[np.generic]]:
        """Every field as named arrays (parameters as 0-d arrays ``param.<name>``), for the store."""
        out: dict[str, NDArray[np.generic]] = {
            f"param.{f.name}": np.asarray(getattr(self.params, f.name)) for f in fields(self.params)
        }
        for name in _ARRAY_FIELDS:
            out[name] = np.asarray(getattr(self, name))
        out["adjacency_indptr"] = np.asarray(self.adjacency_m.indptr, dtype=np.int64)
        out["adjacency_indices"] = np.asarray(self.adjacency_m.indices, dtype=np.int64)
        out["adjacency_dist_m"] = np.asarray(self.adjacency_m.data, dtype=np.float64)
        return out

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray[np.generic]]) -> TopoMap:
        """Rebuild a map from :meth:`to_arrays` output; missing parameters take their defaults."""
        try:
            kwargs = {
                f.name: type(getattr(PAPER, f.name))(arrays[f"param.{f.name}"])
                for f in fields(TopoMapParams)
                if f"param.{f.name}" in arrays
            }
            g = {name: np.asarray(arrays[name], dtype=dtype) for name, dtype in _ARRAY_FIELDS.items()}
            m = g["centres_m"].shape[0]
            adj = csr_array(
                (arrays["adjacency_dist_m"], arrays["adjacency_indices"], arrays["adjacency_indptr"]),
                shape=(m, m),
            )
        except KeyError as exc:
            raise BadInputError("stored map is missing an array", field=str(exc.args[0])) from exc
        return cls(params=TopoMapParams(**kwargs), adjacency_m=adj, **g)


_ARRAY_FIELDS: dict[str, type[np.generic]] = {
    **dict.fromkeys(("centres_m", "frame_dist_m", "headings_rad", "edge_length_m"), np.float64),
    **dict.fromkeys(
        ("chain_ptr", "frame_ids", "frame_node", "chosen_ptr", "chosen", "heading_ptr", "edges"), np.int64
    ),
}


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
    params: TopoMapParams = PAPER,
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
    select = select_frames or partial(
        select_frames_by_heading, heading_tolerance_rad=tol, quality_gain_m=gain
    )
    qual_all = np.concatenate([np.empty(0), *qual])
    ids_all = np.concatenate([chain[:0], *ids])
    order = np.argsort(node, kind="stable")
    ptr = np.r_[0, np.cumsum(np.bincount(node, minlength=m))].astype(np.int64)
    chosen_ptr, chosen = [0], list[int]()
    row = np.arange(chain.size) - chain_ptr[chain]
    per_frame: tuple[NDArray[Any], ...] = (chain, row, ids_all, xy, yaw, dist, qual_all, visit)
    for i in range(m):
        rows = order[ptr[i] : ptr[i + 1]]
        if rows.size == 0:  # a drive stepped over the node (frame step > spacing): no frame saw it
            chosen_ptr.append(len(chosen))
            continue
        pick = np.asarray(select(NodeFrames(i, centres[i], *(a[rows] for a in per_frame)), p.frames_per_node))
        bad = pick.ndim != 1 or pick.size > p.frames_per_node or np.unique(pick).size != pick.size
        bad = bad or (pick.size > 0 and pick.dtype.kind not in "iu")
        if bad or (pick.size and (pick.min() < 0 or pick.max() >= rows.size)):
            raise BadInputError(f"frame selector returned {pick} for node {i}", field="select_frames")
        chosen.extend(rows[pick].tolist())
        chosen_ptr.append(len(chosen))

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
        chosen_ptr=np.asarray(chosen_ptr, dtype=np.int64),
        chosen=np.asarray(chosen, dtype=np.int64),
        heading_ptr=heading_ptr,
        headings_rad=headings,
        edges=edges,
        edge_length_m=lengths,
        adjacency_m=adjacency.shortest_paths(m, edges, lengths, p.max_adjacency_m),
    )
