"""Scores for loop closure: coarse descriptors and candidates, eq. 3 on pairs, diagonal sequences.

The shifted SAD of eq. 3 costs ~35 us per pair of 64x32 frames, too much for every pair of a site.
:mod:`driftmap.core.loop_closure.search` therefore ranks all earlier keyframes of each query by a cheap descriptor
and computes eq. 3 on a few candidates only:

1. **thumbnail**: the patch-normalised frame blurred by a Gaussian about the SAD shift range (such
   texture is fine detail, which a few pixels of shift decorrelate) and area-averaged to 16x8;
2. **centring and projection**: minus the site's mean thumbnail (all tunnel views share a layout),
   optionally PCA-projected, scaled to unit length;
3. **sequence-filtered cosine similarity**: a query block against all earlier frames by one matrix
   product, averaged along diagonals of ``seq_len`` frames of both chains (SeqSLAM on thumbnails,
   the reference axis max-filtered by +-1 frame against uneven keyframe spacing), non-maximum
   suppression along the reference axis (distinct places, not neighbours of one) and top-k.

That is O(N^2 D) multiply-adds, seconds for N = 16,000, in memory bounded by the query block.
Eq. 3 on the candidates, and the diagonals of the confusion matrix, are :mod:`driftmap.core.loop_closure.pair_scores`.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.loop_closure.peaks import NEG, hfilter_max, top_local_maxima

__all__ = [
    "CoarseCandidates",
    "coarse_candidates",
    "describe",
    "descriptor_basis",
    "project",
    "query_blocks",
    "thumbnails",
]

COARSE_BLOCK = 256
"""Queries per matrix product of :func:`coarse_candidates` (and the grid its query ranges follow)."""


def thumbnails(frames: NDArray, size_px: tuple[int, int], blur_px: float = 0.0) -> NDArray[np.float32]:
    """Blur frames, area-average them to thumbnails and flatten them.

    Args:
        frames: ``(N, H, W)`` patch-normalised float32 frames (any real dtype is converted).
        size_px: thumbnail ``(width, height)`` in pixels; clipped to the frame size.
        blur_px: Gaussian sigma applied first, frame pixels (0: none). About the SAD shift range
            makes thumbnails of views a few pixels apart alike.

    Returns:
        ``(N, h * w)`` float32, row-major thumbnails.

    Raises:
        ValueError: ``frames`` is not 3-D or the size is not positive.
    """
    f = np.asarray(frames, dtype=np.float32)
    if f.ndim != 3:
        raise ValueError(f"frames must be (N, H, W), got shape {f.shape}")
    if min(size_px) <= 0:
        raise ValueError(f"size_px must be positive, got {size_px}")
    w, h = min(size_px[0], f.shape[2]), min(size_px[1], f.shape[1])
    out = np.empty((f.shape[0], h * w), dtype=np.float32)
    for i, im in enumerate(f):
        if blur_px > 0:
            im = cv2.GaussianBlur(im, (0, 0), blur_px, borderType=cv2.BORDER_REFLECT_101)
        out[i] = cv2.resize(im, (w, h), interpolation=cv2.INTER_AREA).ravel()
    return out


def describe(thumbs: NDArray, dims: int) -> NDArray[np.float32]:
    """Centre thumbnails on their mean, project onto the leading principal axes, L2-normalise.

    Args:
        thumbs: ``(N, D)`` float32 thumbnails of all frames of a site (:func:`thumbnails`).
        dims: number of principal axes kept; 0 (or >= D) keeps the centred thumbnail.

    Returns:
        ``(N, d)`` float32 unit vectors (zero vectors stay zero), ``d = dims`` or ``D``; the dot
        product of two rows is their cosine similarity in [-1, 1].
    """
    return project(thumbs, *descriptor_basis(thumbs, dims))


def descriptor_basis(thumbs: NDArray, dims: int) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """The mean ``(D,)`` and principal axes ``(D, d)`` (float32) of :func:`describe`; ``(D, 0)`` axes when
    ``dims`` keeps the centred thumbnail (0, >= D, or too few frames).

    Raises:
        ValueError: ``thumbs`` is not ``(N, D)``.
    """
    x = np.asarray(thumbs, dtype=np.float32)
    if x.ndim != 2:
        raise ValueError(f"thumbs must be (N, D), got shape {x.shape}")
    mean = (
        x.mean(axis=0, dtype=np.float64).astype(np.float32)
        if x.shape[0]
        else np.zeros(x.shape[1], np.float32)
    )
    axes = np.zeros((x.shape[1], 0), dtype=np.float32)
    if 0 < dims < min(x.shape):
        # Principal axes from the D x D covariance: cheap for any N.
        c = (x - mean).astype(np.float64)
        cov = (c.T @ c) / max(1, x.shape[0] - 1)
        _, vecs = np.linalg.eigh(cov)
        axes = np.ascontiguousarray(vecs[:, ::-1][:, :dims], dtype=np.float32)
    return mean, axes


def project(thumbs: NDArray, mean: NDArray[np.float32], axes: NDArray[np.float32]) -> NDArray[np.float32]:
    """``(N, d)`` unit descriptors of ``(N, D)`` thumbnails in a basis of :func:`descriptor_basis` (of these
    or of other frames of the site): centred on ``mean``, projected on ``axes`` unless they are ``(D, 0)``.
    Each row is computed alike whatever the other rows (bit for bit).

    Raises:
        ValueError: ``thumbs`` is not ``(N, D)`` with the basis' ``D``.
    """
    x = np.asarray(thumbs, dtype=np.float32)
    if x.ndim != 2 or x.shape[1] != mean.shape[0]:
        raise ValueError(f"thumbs must be (N, {mean.shape[0]}), got shape {x.shape}")
    if x.shape[0] == 0:
        return np.zeros((0, axes.shape[1] or x.shape[1]), dtype=np.float32)
    x = x - mean
    if axes.shape[1]:
        x = np.einsum("nd,dk->nk", x, axes)  # not BLAS, whose rounding of a row depends on the other rows
    norm = np.linalg.norm(x, axis=1, keepdims=True)
    return np.asarray(x / np.maximum(norm, np.float32(1e-12)), dtype=np.float32)


@dataclass(frozen=True)
class CoarseCandidates:
    """Earlier frames of every query most similar by their descriptors.

    Attributes:
        index: ``(N, k)`` int64 global frame indices of the candidates: the sequence-filtered top
            ``top_k`` best first, then the single-frame ones; -1 pads missing ones.
        n_compared: descriptor dot products computed (including the sequence context rows).
    """

    index: NDArray[np.int64]
    n_compared: int


def coarse_candidates(
    desc: NDArray,
    limit: NDArray,
    pos: NDArray,
    *,
    top_k: int,
    top_k_single: int = 0,
    seq_len: int = 1,
    jitter: int = 1,
    nms_radius: int = 2,
    block: int = COARSE_BLOCK,
    queries: tuple[int, int] | None = None,
) -> CoarseCandidates:
    """Rank, for every query frame, the earlier frames it may close a loop with.

    Frames are in one global order (chain after chain). Query ``g`` may match the frames
    ``0 .. limit[g] - 1`` (earlier chains entirely, its own chain outside the recent window), so
    only a lower-left part of the similarity matrix is ever computed.

    Args:
        desc: ``(N, D)`` float32 unit descriptors in global frame order (:func:`describe`).
        limit: ``(N,)`` int, exclusive end of the eligible reference prefix per query; must be
            non-decreasing and ``limit[g] <= g``.
        pos: ``(N,)`` int, index of each frame within its chain (0 at a chain's first frame); the
            diagonal average never crosses a chain start.
        top_k: candidates kept per query by the sequence-filtered similarity, >= 1.
        top_k_single: further candidates by the single-frame similarity (when ``seq_len > 1``),
            other than the sequence candidates: for a revisit's first frames, whose predecessors
            lie elsewhere, sharp turns, where the diagonal breaks, and the frame next to a
            sequence candidate when the diagonal mean, flat over +-``jitter``, peaked beside it.
        seq_len: frames averaged along the diagonal (1 = single-frame similarity).
        jitter: reference frames either side over which each earlier diagonal term is maximised.
        nms_radius: a candidate must be the maximum within this many reference frames either side.
        block: queries per matrix product (memory ~ ``(block + seq_len) x N`` float32 x 4).
        queries: ``(q0, q1)``: rank only queries ``q0 .. q1 - 1`` (``index`` then has ``q1 - q0``
            rows). Both ends must lie on the grid of :func:`query_blocks`, so that every query is
            ranked in the same matrix product as in a run over all queries (same rounding).

    Returns:
        :class:`CoarseCandidates`.

    Raises:
        ValueError: shapes disagree, ``limit`` is not a non-decreasing prefix bound, or ``queries``
            is off the block grid.
    """
    d = np.ascontiguousarray(desc, dtype=np.float32)
    lim = np.asarray(limit, dtype=np.int64)
    p = np.asarray(pos, dtype=np.int64)
    n = d.shape[0] if d.ndim == 2 else -1
    if n < 0 or lim.shape != (n,) or p.shape != (n,):
        raise ValueError(f"desc (N, D), limit (N,), pos (N,) disagree: {d.shape}, {lim.shape}, {p.shape}")
    if top_k < 1 or seq_len < 1 or block < 1:
        raise ValueError("top_k, seq_len and block must be >= 1")
    if n and (np.any(np.diff(lim) < 0) or np.any(lim > np.arange(n)) or np.any(lim < 0)):
        raise ValueError("limit must be non-decreasing with 0 <= limit[g] <= g")
    q0, q1 = queries if queries is not None else (0, n)
    grid = query_blocks(lim, block)
    if not (q0 in grid or q0 == 0) or not (q1 in grid or q1 == n) or q0 > q1:
        raise ValueError(f"queries {q0} .. {q1} are off the block grid {grid[:4]} ... of {n} frames")
    index = np.full((q1 - q0, top_k + top_k_single), -1, dtype=np.int64)
    n_compared = 0
    for b0 in grid[:-1]:
        if not q0 <= b0 < q1:
            continue
        b1 = min(n, b0 + block)
        r = int(lim[b1 - 1])
        e0 = max(0, b0 - seq_len + 1)
        s = d[e0:b1] @ d[:r].T  # (b1 - e0, r) cosine similarities
        n_compared += s.size
        c = _sequence_filter(s, b0 - e0, p[b0:b1], p[:r], seq_len, jitter)
        idx = _select(c, lim[b0:b1], top_k, nms_radius)
        if top_k_single and seq_len > 1:
            idx1 = _select(s[b0 - e0 :], lim[b0:b1], top_k_single, nms_radius)  # s is not used again
            idx1[(idx1[:, :, None] == idx[:, None, :]).any(axis=2)] = -1
            idx = np.concatenate([idx, idx1], axis=1)
        index[b0 - q0 : b1 - q0, : idx.shape[1]] = idx
    return CoarseCandidates(index=index, n_compared=n_compared)


def query_blocks(limit: NDArray, block: int = COARSE_BLOCK) -> list[int]:
    """Starts of :func:`coarse_candidates`' query blocks, then the number of frames ``N``.

    The first block starts at the first query with an eligible reference (``limit > 0``); the
    queries before it have none. A split of the queries at these indices ranks every query exactly
    as a run over all of them.

    Args:
        limit: ``(N,)`` exclusive end of each query's eligible references (non-decreasing).
        block: queries per block.
    """
    lim = np.asarray(limit, dtype=np.int64)
    n = int(lim.size)
    first = int(np.searchsorted(lim, 1))
    return [*range(first, n, block), n]


def _select(c: NDArray[np.float32], lim: NDArray[np.int64], k: int, nms_radius: int) -> NDArray[np.int64]:
    """Top-``k`` eligible local maxima per row of ``c`` (its recent windows overwritten), best first; -1 pads."""
    for i in np.flatnonzero(lim < c.shape[1]).tolist():  # the recent window of the block's queries
        c[i, lim[i] :] = NEG
    return top_local_maxima(c, k, nms_radius)


def _sequence_filter(
    s: NDArray[np.float32],
    q0: int,
    q_pos: NDArray[np.int64],
    r_pos: NDArray[np.int64],
    seq_len: int,
    jitter: int,
) -> NDArray[np.float32]:
    """Mean of ``s`` over the diagonal ending at each (query, reference) entry.

    Rows ``q0 ..`` of ``s`` are the queries, the rows above their predecessors. Term ``l`` pairs
    query ``i - l`` with reference ``j - l`` (max over ``+-jitter`` references); terms crossing
    either chain's start (few) are added with the rest, then taken out row by row and column by column.
    """
    out = np.array(s[q0:], dtype=np.float32)
    if seq_len == 1:
        return out
    s_wide = hfilter_max(s, jitter)
    rows, cols = out.shape
    for lag in range(1, min(seq_len, cols)):
        first = max(0, lag - q0)  # rows above this have no predecessor ``lag`` back in ``s`` (nor in a chain)
        if first >= rows:
            continue
        term = s_wide[q0 + first - lag : q0 + rows - lag, : cols - lag]
        block = out[first:, lag:]
        block += term
        undo_q = np.flatnonzero(q_pos[first:] < lag)  # queries whose predecessor is in another chain
        bad_r = np.flatnonzero(r_pos[lag:] < lag)  # references whose ``j - lag`` is in another chain
        if undo_q.size:
            block[undo_q] -= term[undo_q]
        if bad_r.size:
            keep = np.setdiff1d(np.arange(rows - first), undo_q, assume_unique=True)
            block[np.ix_(keep, bad_r)] -= term[np.ix_(keep, bad_r)]
    # Terms per entry: min(q_pos, r_pos, seq_len - 1) + 1; seq_len except near chain starts.
    out *= np.float32(1.0 / seq_len)
    short_q = np.flatnonzero(q_pos < seq_len - 1)
    short_r = np.flatnonzero(r_pos < seq_len - 1)
    r_count = np.minimum(r_pos, seq_len - 1) + 1
    for i in short_q.tolist():
        out[i] *= seq_len / np.minimum(r_count, q_pos[i] + 1).astype(np.float32)
    if short_r.size:
        full_q = np.setdiff1d(np.arange(rows), short_q, assume_unique=True)
        out[np.ix_(full_q, short_r)] *= (seq_len / r_count[short_r].astype(np.float32))[None, :]
    return out
