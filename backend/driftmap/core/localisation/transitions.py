"""Where the belief may move between frames ([SSLAM] eq. 9-10): the transition matrices pi per reach A_t,
and the direct steps between nodes longer than the minimum reach that a frame may still take.

:class:`TransitionModel` is the predict step of :mod:`driftmap.core.localisation.hmm`'s filter: by the speed
bound (eq. 9-10, :meth:`TransitionModel.predict`) or, with a usable odometry step, by the distance driven
(:meth:`TransitionModel.predict_driven`).
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import csr_array

from driftmap.core.localisation.hmm import HmmParams
from driftmap.core.odometry.step import OdometryStep
from driftmap.core.topomap.distances import transition_matrix
from driftmap.core.types import F64, I64

__all__ = ["TransitionModel", "long_steps"]


def long_steps(adjacency_m: csr_array, from_m: float, nearest: int = 12) -> I64:
    """The direct steps between two nodes of the map at least ``from_m`` long: (K, 2) int64 pairs x < y.

    A pair (x, y) is a direct step when no third node z lies on a shortest path between them
    (A(x, z) + A(z, y) > A(x, y)): a vehicle driving from x to y meets no node in between. Node spacing is
    uneven at junctions and merges, so a few direct steps are longer than the minimum reach A_t; a transition
    matrix without them would never let the belief follow a vehicle across (:class:`TransitionModel`).
    Only each node's ``nearest`` nodes by path are examined (a direct step leads to one of a node's nearest
    nodes in its direction; a junction has a handful of directions), which bounds the work on dense maps.

    Args:
        adjacency_m: (M, M) sparse symmetric shortest-path lengths A, metres.
        from_m: only steps at least this long are returned, metres.
        nearest: the nodes examined from each node.
    """
    adj = csr_array(adjacency_m)
    adj.sort_indices()
    out: set[tuple[int, int]] = set()
    for x in range(adj.shape[0]):
        rx = slice(adj.indptr[x], adj.indptr[x + 1])
        cols, dist = adj.indices[rx], adj.data[rx]
        order = np.argsort(dist, kind="stable")[:nearest]
        for y, a_xy in zip(cols[order].tolist(), dist[order].tolist(), strict=True):
            if y == x or a_xy < from_m or (min(x, y), max(x, y)) in out:
                continue
            ry = slice(adj.indptr[y], adj.indptr[y + 1])
            common, ix, iy = np.intersect1d(cols, adj.indices[ry], assume_unique=True, return_indices=True)
            between = (common != x) & (common != y)
            if not np.any((dist[ix] + adj.data[ry][iy])[between] <= a_xy * (1.0 + 1e-9)):
                out.add((min(x, y), max(x, y)))
    return np.asarray(sorted(out), dtype=np.int64).reshape(-1, 2)


class TransitionModel:
    """Transition matrices pi of eq. 9-10 per frame gap, cached by quantised A_t.

    Args:
        adjacency_m: (M, M) float64 sparse symmetric shortest-path matrix A, metres.
        max_adjacency_m: longest path stored in ``adjacency_m``, metres; a longer reach is treated as
            "anywhere" (uniform prior).
        params: speed, A_t floor and quantum.
        steps: (K, 2) int64 direct steps between nodes longer than ``params.min_a_t_m`` (:func:`long_steps`):
            each is reachable in one frame whatever A_t; None: none.
    """

    def __init__(
        self, adjacency_m: csr_array, max_adjacency_m: float, params: HmmParams, steps: I64 | None = None
    ) -> None:
        self.adjacency_m = adjacency_m
        self.max_adjacency_m = float(max_adjacency_m)
        self.params = params
        self._cache: dict[float, csr_array] = {}
        if steps is not None and steps.size:
            # a direct step longer than the reach still takes one frame: count it as just within the floor
            adj = csr_array(adjacency_m, copy=True)
            inside = params.min_a_t_m * (1.0 - 1e-6)
            adj[steps[:, 0], steps[:, 1]] = np.minimum(adj[steps[:, 0], steps[:, 1]], inside)
            adj[steps[:, 1], steps[:, 0]] = np.minimum(adj[steps[:, 1], steps[:, 0]], inside)
            self.adjacency_m = adj

    def reach_m(self, gap_s: float) -> float:
        """A_t in metres for a timestamp gap (seconds), floored, rounded up to the quantum."""
        p = self.params
        a_t = max(p.min_a_t_m, p.max_speed_mps * max(gap_s, 0.0))
        return math.ceil(a_t / p.a_t_quantum_m - 1e-9) * p.a_t_quantum_m

    def matrix(self, a_t_m: float) -> csr_array | None:
        """(M, M) column-normalised pi for reach ``a_t_m``; None when it exceeds the stored paths."""
        if a_t_m > self.max_adjacency_m + self.params.a_t_quantum_m:
            return None
        key = min(a_t_m, self.max_adjacency_m)
        if key not in self._cache:
            self._cache[key] = transition_matrix(self.adjacency_m, key)
        return self._cache[key]

    def predict(self, belief: F64, gap_s: float) -> F64:
        """(M,) float64 prior ``pi X_{i-1}`` for a frame ``gap_s`` seconds after the last."""
        pi = self.matrix(self.reach_m(gap_s))
        if pi is None:
            return np.full(belief.size, 1.0 / belief.size)
        return np.asarray(pi @ belief, dtype=np.float64)

    def predict_driven(self, belief: F64, gap_s: float, motion: OdometryStep | None) -> F64:
        """(M,) float64 prior ``pi X_{i-1}`` gated by the frame's odometry step ``motion``.

        Without a usable step, eq. 9-10's reach of max speed x the frame gap applies (:meth:`predict`). With
        one, the belief moves by the distance driven: the share ``alpha = (|dx| + sd) / odometry_hop_m`` (at most 1) of
        it takes one minimum-reach transition and the rest stays, so a stopped vehicle's belief (a stationary
        step) does not spread and a moving one's spreads one node per ``odometry_hop_m`` metres driven (:class:`HmmParams`).
        """
        if motion is None:
            return self.predict(belief, gap_s)
        if motion.stationary:
            return belief
        alpha = min(1.0, (abs(motion.dx_m) + motion.sigma_xy_m) / self.params.odometry_hop_m)
        if alpha <= 0.0:
            return belief
        moved = self.predict(belief, 0.0)
        return np.asarray((1.0 - alpha) * belief + alpha * moved, dtype=np.float64)

    @property
    def cached(self) -> int:
        """Number of transition matrices held."""
        return len(self._cache)
