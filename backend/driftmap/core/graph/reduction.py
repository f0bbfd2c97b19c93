"""A keyframe-level pose graph: odometry chains reduced to the frames that matter, and expanded back.

A drive's frames between two frames that carry a closure, a grounding or an anchor are held only by their
odometry steps, so the graph does not need them: the steps between two kept frames (*nodes*) compose into one
relative pose whose covariance is the steps' propagated to first order. The optimiser then solves a node per
few metres of travel instead of one per frame, and every frame is put back afterwards by dead-reckoning each
segment from its first node and spreading the disagreement with its last node over the steps in proportion
to their variance (the exact answer for a linear-Gaussian chain between two fixed ends).

Poses are [x_m, y_m, yaw_rad] rows; steps ``iTj`` are frame j = i+1 in frame i. Covariances are in GTSAM's
tangent space of Pose2 (right perturbation, [x, y, theta] order), as its ``BetweenFactorPose2`` reads them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from driftmap.core.graph.alignment import wrap_angle
from driftmap.core.types import F64

__all__ = ["compose_segments", "expand_chain", "node_frames"]

I64 = NDArray[np.int64]


def node_frames(iTj: F64, required: I64, spacing_m: float, max_steps: int) -> I64:
    """The frames of one drive kept as graph nodes, (M,) increasing.

    The first and last frame, every ``required`` frame, and besides them a frame each time the odometry has
    travelled ``spacing_m`` (forward and sideways distance summed, metres) or taken ``max_steps`` steps since
    the last node. ``spacing_m`` 0 keeps every frame.

    Args:
        iTj: (N-1, 3) odometry steps of the drive.
        required: frame indices that must be nodes (closures, groundings, anchors), any order, repeats allowed.
        spacing_m: travel between nodes, metres.
        max_steps: most steps between two nodes (a vehicle standing still still gets nodes), >= 1.
    """
    n = int(iTj.shape[0]) + 1
    if spacing_m <= 0 or max_steps <= 1 or n <= 2:
        return np.arange(n, dtype=np.int64)
    must = np.zeros(n, dtype=bool)
    must[[0, n - 1]] = True
    must[np.asarray(required, dtype=np.int64)] = True
    travel = np.hypot(iTj[:, 0], iTj[:, 1]).tolist()
    kept, since_m, since_steps = [0], 0.0, 0
    for j in range(1, n):  # frame j ends step j - 1
        since_m += travel[j - 1]
        since_steps += 1
        if must[j] or since_m >= spacing_m or since_steps >= max_steps:
            kept.append(j)
            since_m, since_steps = 0.0, 0
    return np.asarray(kept, dtype=np.int64)


def _adjoint_inverse(steps: F64) -> F64:
    """(K, 3, 3) adjoint maps of the inverses of (K, 3) Pose2 steps."""
    c, s = np.cos(steps[:, 2]), np.sin(steps[:, 2])
    x, y = steps[:, 0], steps[:, 1]
    out = np.zeros((steps.shape[0], 3, 3))
    # Ad(T^-1) = Ad(T)^-1 for Ad(T) = [[c, -s, y], [s, c, -x], [0, 0, 1]]
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = c, s, -(c * y - s * x)
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = -s, c, s * y + c * x
    out[:, 2, 2] = 1.0
    return out


def compose_segments(iTj: F64, covariance: F64, nodes: I64) -> tuple[F64, F64]:
    """The odometry between consecutive nodes as one step each, with its covariance.

    Args:
        iTj: (N-1, 3) steps of the drive.
        covariance: (N-1, 3, 3) covariance of each step.
        nodes: (M,) node frames from :func:`node_frames` (first 0, last N-1).

    Returns:
        ((M-1, 3) composed steps, node k+1 in node k; (M-1, 3, 3) their covariances).
    """
    starts, lengths = nodes[:-1], np.diff(nodes)
    steps = np.zeros((starts.size, 3))
    cov = np.zeros((starts.size, 3, 3))
    for offset in range(int(lengths.max(initial=0))):  # every segment's step ``offset`` at once
        live = np.flatnonzero(lengths > offset)
        step, step_cov = iTj[starts[live] + offset], covariance[starts[live] + offset]
        ad = _adjoint_inverse(step)
        cov[live] = ad @ cov[live] @ ad.transpose(0, 2, 1) + step_cov
        c, s = np.cos(steps[live, 2]), np.sin(steps[live, 2])
        steps[live, 0] += c * step[:, 0] - s * step[:, 1]
        steps[live, 1] += s * step[:, 0] + c * step[:, 1]
        steps[live, 2] += step[:, 2]
    steps[:, 2] = wrap_angle(steps[:, 2])
    return steps, cov


def _segment_cumsum(values: F64, first_step: I64, segment: I64) -> F64:
    """Running sums of ``values`` (K, ...) restarting at each segment; ``first_step`` per segment."""
    total = np.cumsum(values, axis=0)
    before = np.concatenate([np.zeros((1, *values.shape[1:])), total])[first_step]
    return np.asarray(total - before[segment], dtype=np.float64)


def expand_chain(node_wTi: F64, nodes: I64, iTj: F64, covariance: F64) -> F64:
    """Every frame's pose from the nodes' solved poses and the odometry between them.

    Each segment is dead-reckoned from its first node; the heading it misses at its last node is spread over
    the steps in proportion to their heading variance, then the position it misses in proportion to their
    position variance (trace), so the nodes keep their solved poses exactly.

    Args:
        node_wTi: (M, 3) solved poses of the nodes, survey frame.
        nodes: (M,) node frames.
        iTj: (N-1, 3) odometry steps; covariance (N-1, 3, 3) theirs.

    Returns:
        (N, 3) poses of every frame, survey frame.
    """
    n = int(iTj.shape[0]) + 1
    if nodes.size == n:
        return np.array(node_wTi, dtype=np.float64)
    segment = np.searchsorted(nodes, np.arange(n - 1), side="right") - 1  # (N-1,) segment of each step
    first, last = nodes[:-1], nodes[1:] - 1  # step range of each segment
    var_theta = np.maximum(covariance[:, 2, 2], 1e-18)
    var_xy = np.maximum(covariance[:, 0, 0] + covariance[:, 1, 1], 1e-18)
    share_theta = var_theta / np.add.reduceat(var_theta, first)[segment]

    turned = _segment_cumsum(iTj[:, 2], first, segment)  # heading after each step, from the segment's start
    missing = wrap_angle(node_wTi[1:, 2] - node_wTi[:-1, 2] - turned[last])
    dtheta = iTj[:, 2] + missing[segment] * share_theta
    heading_after = node_wTi[segment, 2] + _segment_cumsum(dtheta, first, segment)
    heading_before = heading_after - dtheta
    c, s = np.cos(heading_before), np.sin(heading_before)
    moves = np.column_stack([c * iTj[:, 0] - s * iTj[:, 1], s * iTj[:, 0] + c * iTj[:, 1]])
    xy = node_wTi[segment, :2] + _segment_cumsum(moves, first, segment)
    gap = node_wTi[1:, :2] - xy[last]
    share_xy = _segment_cumsum(var_xy, first, segment) / np.add.reduceat(var_xy, first)[segment]
    xy += gap[segment] * share_xy[:, None]

    out = np.empty((n, 3))
    out[0] = node_wTi[0]
    out[1:, :2], out[1:, 2] = xy, wrap_angle(heading_after)
    out[nodes] = node_wTi
    return out
