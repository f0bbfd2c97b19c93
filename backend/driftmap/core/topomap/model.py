"""The topological map (paper III-A-4) and its parameters: places every N metres of tunnel, their frames.

A :class:`TopoMap` holds a node every ``spacing_m`` of tunnel with the frames that saw it, the connectivity
graph and the sparse shortest-path matrix A that the HMM localiser (III-B) turns into its transition
matrix; :func:`driftmap.core.topomap.build.build_topomap` makes one. Which frames a node keeps is a
pluggable :data:`FrameSelector` (default :func:`select_frames_by_heading`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, fields
from functools import cached_property

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array
from scipy.spatial import cKDTree

from driftmap.core.topomap.distances import neighbours_within, transition_matrix
from driftmap.core.types import F64, I64
from driftmap.errors import BadInputError

__all__ = [
    "TOPOMAP_DEFAULT",
    "TOPOMAP_FAST",
    "TOPOMAP_PAPER",
    "FrameSelector",
    "NodeFrames",
    "TopoMap",
    "TopoMapParams",
    "per_node",
    "select_frames_by_heading",
    "wrap_rad",
]


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


TOPOMAP_PAPER = TopoMapParams()
TOPOMAP_DEFAULT = TOPOMAP_PAPER
TOPOMAP_FAST = TopoMapParams(spacing_m=10.0, merge_radius_m=4.0, frames_per_node=2, max_adjacency_m=40.0)


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


#: Chooses at most ``k`` frames of each node it is given: per node, the (<= k,) int64 positions of its chosen
#: frames in the ``NodeFrames`` rows. It sees every node of the map at once, so it may batch work across them.
FrameSelector = Callable[[Sequence[NodeFrames], int], list[I64]]


def per_node(select_one: Callable[[NodeFrames, int], I64]) -> FrameSelector:
    """The :data:`FrameSelector` that calls ``select_one(node_frames, k)`` on each node in turn."""

    def select(nodes: Sequence[NodeFrames], k: int) -> list[I64]:
        return [select_one(cands, k) for cands in nodes]

    return select


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
        return neighbours_within(self.adjacency_m, node, a_t_m)

    def transition_matrix(self, a_t_m: float) -> csr_array:
        """(M, M) column-normalised HMM transition matrix of eq. 9-10 for A_t = ``a_t_m`` metres."""
        self._check_a_t(a_t_m)
        return transition_matrix(self.adjacency_m, a_t_m)

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
                f.name: type(getattr(TOPOMAP_DEFAULT, f.name))(arrays[f"param.{f.name}"])
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
