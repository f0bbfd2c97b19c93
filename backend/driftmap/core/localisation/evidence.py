"""How b(i) compares with the other places the frame was compared with: the lost test, relocation and the
running distinctness behind the confidence (beyond [SSLAM]).

Lost detection (beyond the paper): a frame is lost when the confidence X_i(b(i)) is below ``lost_confidence``
or the believed place does not look distinctly better than somewhere else: d(i, b(i)) is above
``lost_elsewhere_ratio`` times the least d of the compared nodes (evaluated nodes and a few rotating probe
nodes) more than two frame reaches (2 A_t) of path away from b(i), or above ``lost_distinct_ratio`` times the
median d of the compared nodes. The test is relative to other places of the same map, so it holds in mines
where every tunnel looks much alike (d of the right place only a few per cent below an unrelated one's). A
right track fails this test on single frames (on the medium simulated sites 7.6-8.8 % of all frames were right
but failed it), so an estimate is reported lost only once ``lost_report_frames`` lost frames in a row are
counted; after ``lost_frames`` the belief becomes uniform, so the next frame searches the whole map. A vehicle
that stands where the map's views match poorly looks lost frame after frame, but it shows the same view again
and again: a "still" frame (its view changed less than ``still_ratio`` times its least d to the map since the
previous frame) adds no evidence of being elsewhere, so once the belief has followed ``confirm_frames`` moving
frames since its last global start, still lost frames leave the count where it was (and are reported lost only
if it had reached ``lost_report_frames``).

Relocation (beyond the paper): a compared far node (as above) whose d is at least ``relocate_ratio`` times
below d(i, b(i)) gets ``relocate_share`` of the belief after the update, a second hypothesis that the next
frames confirm or drop. It is then the belief's peak, and the frame reports it (eq. 11 on the belief the
frame leaves, so the estimate and the stored state agree; the lost test and distinctness are those of the new
b(i)). A belief stuck on a look-alike can fail the lost test on most frames and still never reach
``lost_frames`` in a row; when a probe shows the true place clearly better, this moves it.

The running distinctness (:func:`track_distinct`) is this frame's ``1 - d(i, b(i)) / d_other`` averaged over
the frames of one track; the localiser's raw confidence is X_i(b(i)) times it.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array

from driftmap.core.types import I64

__all__ = ["distinctness", "elsewhere", "is_still", "judge", "near", "track_distinct"]


def near(adjacency_m: csr_array, node: int, within_m: float) -> I64:
    """(k,) int64 the nodes within ``within_m`` metres of path of ``node`` (adjacency_m: (M, M) sparse path
    lengths A, metres; two frame reaches count as the same place)."""
    row = slice(adjacency_m.indptr[node], adjacency_m.indptr[node + 1])
    return np.asarray(adjacency_m.indices[row][adjacency_m.data[row] <= within_m], dtype=np.int64)


def distinctness(d: NDArray[np.floating], d_best: float) -> float:
    """1 - d_best / median of the finite scores d (K,): 0 when the best is typical, near 1 when it stands
    out."""
    finite = d[np.isfinite(d)]
    if finite.size == 0 or not np.isfinite(d_best):
        return 0.0
    med = float(np.median(finite))
    return 1.0 - d_best / med if med > 0 else 0.0


def elsewhere(
    compared: I64, d: NDArray[np.floating], best: int, d_here: float, near_best: I64
) -> tuple[float, int]:
    """(d(b(i)) / least d of the ``compared`` (K,) nodes, scores ``d`` (K,), that are neither ``best`` nor in
    ``near_best``, that node); (0, -1) if there is none."""
    far = ~np.isin(compared, near_best) & (compared != best) & np.isfinite(d)
    if not far.any():
        return 0.0, -1
    k = int(np.argmin(np.where(far, d, np.inf)))
    d_far = float(d[k])
    ratio = d_here / d_far if d_far > 0 and np.isfinite(d_here) else float("inf")
    return ratio, int(compared[k])


def judge(
    adjacency_m: csr_array, best: int, compared: I64, d_all: NDArray[np.floating], far_m: float
) -> tuple[float, I64, float, int]:
    """How ``best`` compares with the other ``compared`` (K,) nodes of scores ``d_all`` (K,): (d(b) / median
    d, the nodes within ``far_m`` metres of path of it, :func:`elsewhere`'s ratio and far node)."""
    at_best = d_all[compared == best]
    d_here = float(at_best[0]) if at_best.size else float(np.min(d_all, initial=np.inf))
    near_best = near(adjacency_m, best, far_m)
    ratio, far_best = elsewhere(compared, d_all, best, d_here, near_best)
    return 1.0 - distinctness(d_all, d_here), near_best, ratio, far_best


def track_distinct(
    last_node: int, last_distinct: float, best: int, distinct: float, near_best: I64, memory: float
) -> float:
    """The running distinctness of the track that ends at ``best``: this frame's ``distinct`` averaged
    exponentially (weight ``memory``) with the last frame's running value ``last_distinct`` when the last
    b(i), ``last_node``, is ``best`` or one of its ``near_best`` nodes; with 0 after a jump or a global start
    (a new track earns its confidence frame by frame)."""
    same_track = last_node >= 0 and (best == last_node or last_node in near_best)
    return (1.0 - memory) * (last_distinct if same_track else 0.0) + memory * distinct


def is_still(query: NDArray[np.float32], last: NDArray[np.float32], d_least: float, ratio: float) -> bool:
    """True when the view barely changed since the last frame: mean |query - last| (both (h, w)) below
    ``ratio`` x the least d of this frame to the map (the vehicle stands; a moving camera changes its view
    about as much as it differs from the best reference)."""
    if ratio <= 0 or last.shape != query.shape or not np.isfinite(d_least):
        return False
    return float(np.mean(np.abs(query - last))) < ratio * d_least
