"""SeqSLAM (Milford & Wyeth, ICRA 2012) as OpenSeqSLAM runs it, on a difference matrix, for comparison.

The three steps of the published method, with OpenSeqSLAM's defaults:

1. **Difference matrix**: the mean absolute difference of patch-normalised 64x32 thumbnails. The caller
   passes it in; ``bench/vpr_defaults.py`` gives it driftmap's (``core.place_recognition.single.distance_matrix``, preset
   ``route``: 64-px-wide thumbnails, 8-px patch normalisation, no shifts), so both methods see the same
   front end and differ only in what they do with it.
2. **Local contrast enhancement**: each entry is normalised by the mean and standard deviation of the
   query's differences to the references within ``+-window // 2`` of it (``R_window`` = 10); then the
   matrix is shifted so that its least entry is 0.
3. **Sequence search**: for query i, the straight lines through the matrix over the ``ds + 1`` queries
   centred on i (``ds`` = 10), at every reference start s and every velocity v in 0.8, 0.9, ... 1.2
   references per query, each summing the enhanced differences at reference ``s + floor(k v)`` for the
   k-th query of the sequence; the best line of each start scores it. The match is the best start (plus
   the offset of i in its sequence), and its score is the ratio of the best start's sum to the best sum
   of a start more than ``R_window / 2`` references away: lower is more distinct (the PR sweep thresholds
   this ratio; here the score is ``1 - ratio``, higher = more confident).

One deviation, in SeqSLAM's favour: OpenSeqSLAM leaves the first and last ``ds / 2`` queries unmatched (no
centred sequence fits); here their sequence is moved to fit inside the traversal, so every query is matched.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from driftmap.core.place_recognition.single import Matches

F64 = NDArray[np.float64]


def enhance(d: NDArray[np.floating], window: int = 10) -> F64:
    """Local contrast enhancement of a ``(Q, D)`` difference matrix along the references.

    Returns:
        ``(D, Q)`` float64 (references x queries, SeqSLAM's layout), least entry 0.
    """
    dd = np.asarray(d, dtype=np.float64).T
    n = dd.shape[0]
    half = window // 2
    out = np.empty_like(dd)
    for i in range(n):
        v = dd[max(0, i - half) : min(n, i + half + 1)]
        out[i] = (dd[i] - v.mean(axis=0)) / np.maximum(v.std(axis=0, ddof=1), 1e-12)
    return out - out.min()


def search(dd: F64, ds: int = 10, v_min: float = 0.8, v_max: float = 1.2, window: int = 10) -> Matches:
    """The sequence search over an enhanced ``(D, Q)`` matrix (:func:`enhance`); the velocities are
    OpenSeqSLAM's: ``m / ds`` references per query for every whole move m from ``v_min ds`` to ``v_max ds``.

    Returns:
        :class:`~driftmap.core.place_recognition.single.Matches`: the matched reference of each query and ``1 - ratio``.
    """
    n, q = dd.shape
    if q <= ds:
        raise ValueError(f"need more than ds = {ds} queries, got {q}")
    k = np.arange(ds + 1)
    # references past the end repeat the last one (OpenSeqSLAM clips the index)
    pad = np.vstack([dd, np.repeat(dd[-1:], int(np.ceil(ds * v_max)) + 1, axis=0)])
    starts = np.clip(np.arange(q) - ds // 2, 0, q - 1 - ds)
    best = np.full((n, q), np.inf)
    for move in range(round(v_min * ds), round(v_max * ds) + 1):
        total = np.zeros((n, q))
        for kk, off in zip(k, (k * move) // ds, strict=True):
            total += pad[off : off + n][:, starts + kk]
        best = np.minimum(best, total)
    start = np.argmin(best, axis=0)
    least = best[start, np.arange(q)]
    outside = np.abs(np.arange(n)[:, None] - start[None, :]) > window // 2
    second = np.where(outside, best, np.inf).min(axis=0)
    ratio = least / np.maximum(second, 1e-12)
    match = np.minimum(start + (np.arange(q) - starts), n - 1)
    return Matches(db_index=match.astype(np.int64), score=1.0 - ratio)


def seqslam(d: NDArray[np.floating]) -> Matches:
    """SeqSLAM with OpenSeqSLAM's defaults on a ``(Q, D)`` difference matrix."""
    return search(enhance(d))
