"""Distances on the map's graph: the sparse shortest-path matrix A and the HMM transitions it gives.

The graph's shortest-path matrix A(x, y) (III-A-4) feeds the HMM transition matrix of III-B (eq. 9-10):
``beta(k) = 1 if k < A_t else 0``, every column normalised to sum to 1. A dense A is quadratic in the number
of nodes and only short paths matter to the HMM (A_t is the distance a vehicle travels in one frame
interval), so A is stored sparsely up to a maximum distance: a missing off-diagonal entry means "further than
the stored maximum" (infinite for the HMM) and the diagonal is zero by definition, never stored. Matrices are
``scipy.sparse.csr_array`` of shape (M, M) over node indices 0..M-1, distances in metres.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array
from scipy.sparse.csgraph import dijkstra

from driftmap.core.topomap.adjacency import MIN_EDGE_M
from driftmap.errors import BadInputError

__all__ = ["neighbours_within", "shortest_paths", "transition_matrix"]

#: Dijkstra runs on blocks of source nodes so that its dense (block, M) output stays below this many cells.
_BLOCK_CELLS = 1 << 22


def shortest_paths(
    n_nodes: int, edges: NDArray[np.int64], lengths_m: NDArray[np.float64], max_m: float
) -> csr_array:
    """Sparse matrix A of shortest-path lengths up to ``max_m`` (paper III-A-4).

    Args:
        n_nodes: number of nodes M.
        edges: (E, 2) int node pairs of the undirected graph, no self-edges.
        lengths_m: (E,) float64 positive edge lengths, metres.
        max_m: longest path length stored, metres.

    Returns:
        (M, M) float64 csr_array, exactly symmetric, holding A(x, y) for every x != y whose shortest path is
        at most ``max_m``; the diagonal (zero) and longer paths are not stored.
    """
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    lengths_m = np.maximum(np.asarray(lengths_m, dtype=np.float64).reshape(-1), MIN_EDGE_M)
    if lengths_m.shape[0] != edges.shape[0]:
        raise BadInputError("one length per edge is required", field="lengths_m")
    if n_nodes == 0:
        return csr_array((0, 0), dtype=np.float64)
    graph = csr_array(
        (
            np.concatenate([lengths_m, lengths_m]),
            (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]]),
        ),
        shape=(n_nodes, n_nodes),
    )
    rows, cols, vals = [], [], []
    block = max(1, _BLOCK_CELLS // n_nodes)
    for start in range(0, n_nodes, block):
        sources = np.arange(start, min(start + block, n_nodes))
        dist = np.asarray(dijkstra(graph, directed=False, indices=sources, limit=max_m), dtype=np.float64)
        # Keep the upper triangle only, then mirror: exact symmetry whatever the summation order.
        r, c = np.nonzero(np.isfinite(dist) & (np.arange(n_nodes)[None, :] > sources[:, None]))
        rows.append(sources[r])
        cols.append(c)
        vals.append(dist[r, c])
    r_all, c_all, v_all = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    return csr_array(
        (np.r_[v_all, v_all], (np.r_[r_all, c_all], np.r_[c_all, r_all])), shape=(n_nodes, n_nodes)
    )


def neighbours_within(
    adjacency_m: csr_array, node: int, a_t_m: float
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Nodes a vehicle at ``node`` can reach in one frame interval: A(node, y) < a_t_m, itself included.

    Args:
        adjacency_m: (M, M) sparse shortest-path matrix from :func:`shortest_paths`, metres.
        node: index of the node.
        a_t_m: A_t of paper eq. 10, metres; must not exceed the maximum distance stored in the matrix.

    Returns:
        (K,) int64 node indices sorted by distance (``node`` first) and their (K,) float64 distances, metres.
    """
    if not 0 <= node < adjacency_m.shape[0]:
        raise BadInputError(f"node {node} is not in a map of {adjacency_m.shape[0]} nodes", field="node")
    lo, hi = adjacency_m.indptr[node], adjacency_m.indptr[node + 1]
    idx = np.asarray(adjacency_m.indices[lo:hi], dtype=np.int64)
    dist = np.asarray(adjacency_m.data[lo:hi], dtype=np.float64)
    keep = dist < a_t_m
    idx = np.r_[np.int64(node), idx[keep]]
    dist = np.r_[0.0, dist[keep]]
    order = np.argsort(dist, kind="stable")
    return idx[order], dist[order]


def transition_matrix(adjacency_m: csr_array, a_t_m: float) -> csr_array:
    """HMM transition matrix pi of paper eq. 9-10 from the sparse shortest-path matrix.

    ``pi[y, x]`` is the probability of moving from node x to node y in one frame interval: uniform over
    every y with A(x, y) < A_t (x itself always included, A(x, x) = 0), so every column sums to 1.

    Args:
        adjacency_m: (M, M) sparse shortest-path matrix from :func:`shortest_paths`, metres.
        a_t_m: A_t, the furthest a vehicle can travel in one frame interval, metres (> 0). It must not
            exceed the maximum distance stored in ``adjacency_m``, or reachable nodes would be missing.

    Returns:
        (M, M) float64 csr_array with columns summing to 1.
    """
    if not a_t_m > 0:
        raise BadInputError(f"A_t must be positive, got {a_t_m}", field="a_t_m")
    n = adjacency_m.shape[0]
    coo = adjacency_m.tocoo()
    keep = coo.data < a_t_m
    rows = np.r_[np.asarray(coo.row, dtype=np.int64)[keep], np.arange(n, dtype=np.int64)]
    cols = np.r_[np.asarray(coo.col, dtype=np.int64)[keep], np.arange(n, dtype=np.int64)]
    per_column = np.bincount(cols, minlength=n).astype(np.float64)
    return csr_array((1.0 / per_column[cols], (rows, cols)), shape=(n, n))
