"""The map a localiser runs on ([SSLAM] III-B): each node's reference thumbnails, centre and adjacency.

:class:`LocaliserMap` is what :class:`driftmap.core.localisation.localiser.Localiser` reads of a stored map;
:func:`build_localiser_map` makes one from a :class:`~driftmap.core.topomap.build.TopoMap` and the thumbnails of its
frames. It is immutable and shared: several localisers (one per vehicle) can run on one map, each with its own
:class:`~driftmap.core.localisation.hmm.HmmParams`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array
from scipy.spatial import cKDTree

from driftmap.core.imaging.params import IMAGES_DEFAULT, ImageParams
from driftmap.core.localisation import evidence, hmm, transitions
from driftmap.core.localisation.turns import TurnParams, map_turns
from driftmap.core.topomap.model import TopoMap
from driftmap.core.types import F32, F64, I64
from driftmap.errors import BadInputError

__all__ = ["LocaliserMap", "build_localiser_map", "mapped_paths"]


@dataclass(frozen=True, eq=False)
class LocaliserMap:
    """What the localiser needs of a stored map.

    Attributes:
        thumbs: (S, H, W) float32 pre-processed reference thumbnails, node j's in ``node_ptr[j]:node_ptr[j+1]``.
        node_ptr: (M + 1,) int64 offsets of each node's thumbnails.
        centres_m: (M, 2) float64 node centres, survey frame, metres.
        adjacency_m: (M, M) float64 symmetric sparse shortest-path lengths A(x, y), metres.
        max_adjacency_m: longest path stored in ``adjacency_m``, metres.
        image_params: the pre-processing that made ``thumbs``; query frames get the same.
        edges: (E, 2) int64 node pairs driven between directly (the tunnels as segments between centres);
            the continuous track follows them (:func:`driftmap.core.localisation.tunnels.snap`); (0, 2): none.
        ref_xy_m: (S, 2) float64 where each reference thumbnail was taken: its frame's optimised pose, survey
            frame, metres; the place fix of a frame is the position of the reference it matched best, finer
            than the node centre. None: unknown (the fix is the node centre).
        path_xy_m: (P, 2) float64 vertices of the mapped trajectories (the optimised poses of the mapping
            drives, :func:`mapped_paths`), survey frame, metres; the continuous track follows them. None:
            unknown (the track follows ``edges``).
        path_segments: (Q, 2) int64 vertex pairs of ``path_xy_m`` driven between directly.
    """

    thumbs: NDArray[np.float32]
    node_ptr: I64
    centres_m: F64
    adjacency_m: csr_array
    max_adjacency_m: float
    image_params: ImageParams = IMAGES_DEFAULT
    edges: I64 = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    ref_xy_m: F64 | None = None
    path_xy_m: F64 | None = None
    path_segments: I64 = field(default_factory=lambda: np.zeros((0, 2), dtype=np.int64))
    _long_steps: dict[float, I64] = field(default_factory=dict, init=False, repr=False)
    _turns: dict[TurnParams, F64] = field(default_factory=dict, init=False, repr=False)
    _path_index: list[tuple[cKDTree, float]] = field(default_factory=list, init=False, repr=False)

    def __post_init__(self) -> None:
        m = self.centres_m.shape[0]
        if self.thumbs.ndim != 3 or self.thumbs.dtype != np.float32:
            raise BadInputError(f"thumbs must be (S, H, W) float32, got {self.thumbs.shape}", field="thumbs")
        if self.centres_m.shape != (m, 2) or m == 0:
            raise BadInputError(
                f"centres_m must be (M, 2), M > 0, got {self.centres_m.shape}", field="centres_m"
            )
        if self.node_ptr.shape != (m + 1,):
            raise BadInputError(f"node_ptr must be ({m + 1},), got {self.node_ptr.shape}", field="node_ptr")
        hmm.check_node_ptr(self.node_ptr, self.thumbs.shape[0])
        if self.adjacency_m.shape != (m, m):
            raise BadInputError(f"adjacency_m must be ({m}, {m})", field="adjacency_m")
        edges = np.asarray(self.edges)
        if edges.ndim != 2 or edges.shape[1] != 2 or (edges.size and (edges.min() < 0 or edges.max() >= m)):
            raise BadInputError(f"edges must be (E, 2) node indices below {m}", field="edges")
        if self.ref_xy_m is not None and self.ref_xy_m.shape != (self.thumbs.shape[0], 2):
            raise BadInputError(
                f"ref_xy_m must be ({self.thumbs.shape[0]}, 2), got {self.ref_xy_m.shape}", field="ref_xy_m"
            )
        if self.path_xy_m is not None:
            n, seg = self.path_xy_m.shape[0], np.asarray(self.path_segments)
            if self.path_xy_m.shape != (n, 2) or not np.all(np.isfinite(self.path_xy_m)):
                raise BadInputError("path_xy_m must be (P, 2) finite metres", field="path_xy_m")
            if seg.ndim != 2 or seg.shape[1] != 2 or (seg.size and (seg.min() < 0 or seg.max() >= n)):
                raise BadInputError(
                    f"path_segments must be (Q, 2) vertex indices below {n}", field="path_segments"
                )

    def fix_m(self, node: int, ref: int) -> F64:
        """(2,) float64 the place fix of a frame whose b(i) is ``node`` and whose best reference frame was
        row ``ref`` of ``thumbs`` (-1: unknown): where that reference was taken, else the node centre."""
        if self.ref_xy_m is None or not self.node_ptr[node] <= ref < self.node_ptr[node + 1]:
            return np.asarray(self.centres_m[node], dtype=np.float64)
        return np.asarray(self.ref_xy_m[ref], dtype=np.float64)

    def place_fix(self, best: int, compared: I64, d: F32, refs: I64, reach_m: float) -> F64:
        """(2,) float64 survey metres: where the reference frame that matched a frame best was taken, among
        the compared nodes within ``reach_m`` of path of b(i) (``best``) and b(i) itself (``compared`` (K,)
        nodes, their scores ``d`` (K,) and best reference rows ``refs`` (K,),
        :func:`driftmap.core.localisation.hmm.compare_references`).

        b(i) moves on only once the next node's views match better than its own, so its own best reference
        trails a moving vehicle; the next node's nearest reference, compared in the same frame, often
        matches better already. The node centre when the map has no reference positions.
        """
        around = np.isin(compared, evidence.near(self.adjacency_m, best, reach_m)) | (compared == best)
        k = int(np.argmin(np.where(around, d, np.inf)))
        if not around[k] or not np.isfinite(d[k]):
            return np.asarray(self.centres_m[best], dtype=np.float64)
        return self.fix_m(int(compared[k]), int(refs[k]))

    def edges_near(self, nodes: I64) -> I64:
        """(K, 2) int64 the edges with an end among ``nodes``."""
        if self.edges.size == 0:
            return self.edges
        keep = np.isin(self.edges, nodes).any(axis=1)
        return np.asarray(self.edges[keep], dtype=np.int64)

    def path_near(self, xy_m: F64, radius_m: float) -> I64:
        """(K, 2) int64 the mapped path segments (:attr:`path_segments`) that may pass within ``radius_m``
        metres of the survey point (2,) ``xy_m`` (their midpoints within ``radius_m`` plus the longest
        half segment); (0, 2) without paths."""
        if self.path_xy_m is None or self.path_segments.size == 0:
            return np.zeros((0, 2), dtype=np.int64)
        if not self._path_index:
            ends = self.path_xy_m[self.path_segments]
            half = 0.5 * float(np.max(np.hypot(*(ends[:, 1] - ends[:, 0]).T)))
            self._path_index.append((cKDTree(ends.mean(axis=1)), half))
        tree, half = self._path_index[0]
        near = tree.query_ball_point(np.asarray(xy_m, dtype=np.float64), radius_m + half)
        return np.asarray(self.path_segments[np.sort(np.asarray(near, dtype=np.int64))], dtype=np.int64)

    @property
    def n_nodes(self) -> int:
        """Number of nodes M."""
        return int(self.centres_m.shape[0])

    def nearest_node(self, x_m: float, y_m: float) -> int:
        """The node whose centre is nearest the survey point (x_m, y_m), metres."""
        if not (np.isfinite(x_m) and np.isfinite(y_m)):
            raise BadInputError(f"need a finite survey point, got ({x_m}, {y_m})", field="start")
        return int(np.argmin(np.hypot(self.centres_m[:, 0] - x_m, self.centres_m[:, 1] - y_m)))

    def turns(self, params: TurnParams) -> F64:
        """(M, K) float64 each node's mapped heading changes over ``params.window_m`` of path, radians
        (:func:`driftmap.core.localisation.turns.map_turns`, computed once per window)."""
        if params not in self._turns:
            self._turns[params] = map_turns(self.centres_m, self.edges, params)
        return self._turns[params]

    def long_steps(self, from_m: float) -> I64:
        """(K, 2) int64 direct steps between nodes at least ``from_m`` long (computed once per length).

        See :func:`driftmap.core.localisation.transitions.long_steps`; the transition model lets the belief take each in one frame.
        ``from_m`` is the filter's minimum reach (``HmmParams.min_a_t_m``), so localisers with other
        parameters on one shared map each get their own steps.
        """
        if from_m not in self._long_steps:
            self._long_steps[from_m] = transitions.long_steps(self.adjacency_m, from_m)
        return self._long_steps[from_m]


def build_localiser_map(
    topomap: TopoMap,
    thumbs_by_flat_frame_index: NDArray[np.float32],
    image_params: ImageParams = IMAGES_DEFAULT,
    frame_xy_m: F64 | None = None,
) -> LocaliserMap:
    """The localiser's map from a :class:`TopoMap` and the thumbnails of its frames.

    Args:
        topomap: the stored map; each node's chosen frames become its references.
        thumbs_by_flat_frame_index: (F, H, W) float32 pre-processed thumbnails indexed by the map's flat
            frame index (every frame of every chain; only the chosen ones are read).
        image_params: the pre-processing that made the thumbnails.
        frame_xy_m: (F, 2) float64 optimised positions of the map's frames by flat frame index, survey frame,
            metres; the chosen ones become the references' positions (:attr:`LocaliserMap.ref_xy_m`), all of
            them the mapped paths (:func:`mapped_paths`). None: fixes at node centres, the track on ``edges``.

    Returns:
        The :class:`LocaliserMap`.
    """
    thumbs = np.asarray(thumbs_by_flat_frame_index, dtype=np.float32)
    if thumbs.ndim != 3 or thumbs.shape[0] != topomap.frame_ids.shape[0]:
        raise BadInputError(
            f"need ({topomap.frame_ids.shape[0]}, H, W) thumbnails, got {thumbs.shape}",
            field="thumbs_by_flat_frame_index",
        )
    path_xy_m, path_segments = (None, np.zeros((0, 2), dtype=np.int64))
    if frame_xy_m is not None:  # the flat frame index runs chain by chain, each in frame order
        path_xy_m, path_segments = mapped_paths(
            frame_xy_m, topomap.chain_ptr, max_gap_m=topomap.params.max_frame_step_m
        )
    return LocaliserMap(
        thumbs=np.ascontiguousarray(thumbs[topomap.chosen]),
        node_ptr=np.asarray(topomap.chosen_ptr, dtype=np.int64),
        centres_m=np.asarray(topomap.centres_m, dtype=np.float64),
        adjacency_m=topomap.adjacency_m,
        max_adjacency_m=float(topomap.params.max_adjacency_m),
        image_params=image_params,
        edges=np.asarray(topomap.edges, dtype=np.int64).reshape(-1, 2),
        ref_xy_m=None if frame_xy_m is None else np.asarray(frame_xy_m, dtype=np.float64)[topomap.chosen],
        path_xy_m=path_xy_m,
        path_segments=path_segments,
    )


def mapped_paths(xy_m: F64, chain_ptr: I64, step_m: float = 1.0, max_gap_m: float = 10.0) -> tuple[F64, I64]:
    """The mapped trajectories as polylines for the continuous track to follow.

    Args:
        xy_m: (F, 2) float64 optimised positions of the map's frames by flat frame index, survey frame,
            metres; NaN rows (a frame without a pose) break their chain.
        chain_ptr: (C + 1,) int64 offsets of the drives' chains in the flat frame index.
        step_m: a vertex is kept every this much travel along a chain, metres (a standing vehicle's poses
            collapse to one).
        max_gap_m: consecutive kept vertices further apart than this are not joined (a gap in the drive).

    Returns:
        (P, 2) float64 vertices and (Q, 2) int64 segments (vertex pairs, consecutive along a chain).
    """
    xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
    vertices: list[tuple[float, float]] = []
    segments: list[tuple[int, int]] = []
    for c in range(len(chain_ptr) - 1):
        last = -1
        for x, y in xy[int(chain_ptr[c]) : int(chain_ptr[c + 1])].tolist():
            if not (math.isfinite(x) and math.isfinite(y)):
                last = -1
                continue
            if last >= 0:
                gap = math.hypot(x - vertices[last][0], y - vertices[last][1])
                if gap < step_m:
                    continue
                if gap <= max_gap_m:
                    segments.append((last, len(vertices)))
            vertices.append((x, y))
            last = len(vertices) - 1
    return (
        np.asarray(vertices, dtype=np.float64).reshape(-1, 2),
        np.asarray(segments, dtype=np.int64).reshape(-1, 2),
    )
