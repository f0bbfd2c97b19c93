"""A cache of eq. 3 scores of frame pairs, and sequence scores of diagonals.

The loop-closure search (:mod:`driftmap.core.loop_closure.blocks`) computes the shifted SAD of eq. 3 only
on the pairs its coarse candidates (:mod:`driftmap.core.loop_closure.descriptors`) and their sequence checks
ask for: :func:`~driftmap.core.imaging.sad.sad_pairs` scores any list of pairs in batches, :class:`PairCache`
keeps each pair's score so no pair is computed twice, and :class:`DiagonalScorer` scores short diagonals of
the confusion matrix from it (SeqSLAM on full-resolution frames).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.params import SAD_DEFAULT, SadParams
from driftmap.core.imaging.sad import sad_pairs

__all__ = ["DiagonalScorer", "PairCache"]


class PairCache:
    """Eq. 3 scores of frame pairs, computed in batches on demand and kept.

    Args:
        frames: ``(N, H, W)`` float32 patch-normalised frames, addressed by global index.
        params: the SAD shift ranges.
    """

    def __init__(self, frames: NDArray[np.float32], params: SadParams = SAD_DEFAULT) -> None:
        self.frames, self.params = frames, params
        self.n = frames.shape[0]
        self.entries: dict[int, tuple[float, int, int]] = {}  # i * n + j -> (d, dx, dy)
        self.n_computed = 0  # full SAD comparisons made so far

    def fetch(self, qi: NDArray[np.int64], rj: NDArray[np.int64]) -> NDArray[np.float32]:
        """d of each pair ``(qi[p], rj[p])`` (any shape), computing the missing ones in one batch."""
        keys = (np.asarray(qi, dtype=np.int64) * self.n + np.asarray(rj, dtype=np.int64)).ravel()
        missing = np.array(sorted({k for k in keys.tolist() if k not in self.entries}), dtype=np.int64)
        if missing.size:
            res = sad_pairs(self.frames, missing // self.n, missing % self.n, self.params)
            self.n_computed += missing.size
            for k, d, (dx, dy) in zip(missing.tolist(), res.d.tolist(), res.shift_px.tolist(), strict=True):
                self.entries[k] = (d, dx, dy)
        out = np.array([self.entries[k][0] for k in keys.tolist()], dtype=np.float32)
        return out.reshape(np.shape(qi))

    def get(self, i: int, j: int) -> tuple[float, int, int]:
        """``(d, dx, dy)`` of a pair already fetched."""
        return self.entries[i * self.n + j]

    def background(self, limit: NDArray[np.int64], n_pairs: int, seed: int) -> tuple[float, float]:
        """Median and robust sigma (1.4826 MAD) of d over random eligible pairs.

        Args:
            limit: ``(N,)`` exclusive end of each query's eligible references (see
                :func:`coarse_candidates`); pairs are drawn uniformly from all eligible pairs.
            n_pairs: pairs drawn (at most the number of eligible pairs), with replacement.
            seed: of the draw.
        """
        q = np.flatnonzero(limit > 0)
        rng = np.random.default_rng(seed)
        gq = rng.choice(q, size=int(min(n_pairs, limit.sum())), p=limit[q] / limit[q].sum())
        rj = np.minimum((rng.random(gq.size) * limit[gq]).astype(np.int64), limit[gq] - 1)
        d = self.fetch(gq, rj)
        median = float(np.median(d))
        return median, 1.4826 * float(np.median(np.abs(d - median)))


class DiagonalScorer:
    """SeqSLAM-style scores of short diagonals of the confusion matrix, from a :class:`PairCache`.

    Query frame ``i - l`` (``l = 0 .. seq_len - 1``) pairs with reference ``j - round(v l)`` for each
    slope ``v`` (reference frames per query frame; negative: the reference drive passed the other
    way, e.g. reversing with the same heading). Every pair must lie inside the two chains and be
    eligible (``r < limit[i - l]``). Slopes +-1 (keyframes at equal spacing) are tried first; the
    others only where those do not already give a mean below ``d_t`` with ``min_hits`` hits.

    Args:
        cache: eq. 3 scores.
        chain: ``(N,)`` chain of each frame; ``pos``: ``(N,)`` index in its chain; ``limit``:
            ``(N,)`` exclusive end of the eligible references of each query.
        seq_len: frames in a diagonal.
        slopes: the slopes ``v`` tried; the best one counts.
        thresholds: ``(d_hit, d_t, min_hits)``: a pair with ``d < d_hit`` is a hit; a diagonal with
            mean below ``d_t`` and ``min_hits`` hits needs no other slope.
    """

    def __init__(
        self,
        cache: PairCache,
        chain: NDArray[np.int64],
        pos: NDArray[np.int64],
        limit: NDArray[np.int64],
        seq_len: int,
        slopes: tuple[float, ...],
        thresholds: tuple[float, float, int],
    ) -> None:
        self.cache, self.chain, self.pos, self.limit = cache, chain, pos, limit
        self.seq_len, self.n = seq_len, chain.size
        self.d_hit, self.d_t, self.min_hits = thresholds
        lags = np.arange(seq_len)
        offsets = np.unique(np.rint(np.outer(slopes, lags)).astype(np.int64), axis=0)
        unit = np.all(np.abs(offsets) == lags, axis=1)
        if not unit.any():
            unit[:] = True
        self.first: NDArray[np.int64] = offsets[unit]
        self.rest: NDArray[np.int64] = offsets[~unit]

    def scores(
        self, qi: NDArray[np.int64], rj: NDArray[np.int64]
    ) -> tuple[NDArray[np.float32], NDArray[np.int64]]:
        """Best mean d over the slopes of the diagonals ending at ``(qi[m], rj[m])``, and its hits.

        Missing scores are computed in batches. Returns ``(M,)`` float32 means (inf when no
        diagonal fits) and ``(M,)`` int64 hits of the best slope.
        """
        mean, hits = self._scores(qi, rj, self.first)
        redo = np.flatnonzero(~((mean < self.d_t) & (hits >= self.min_hits)))
        if self.rest.size and redo.size:
            mean2, hits2 = self._scores(qi[redo], rj[redo], self.rest)
            better = mean2 < mean[redo]
            mean[redo[better]], hits[redo[better]] = mean2[better], hits2[better]
        return mean, hits

    def _scores(
        self, qi: NDArray[np.int64], rj: NDArray[np.int64], offsets: NDArray[np.int64]
    ) -> tuple[NDArray[np.float32], NDArray[np.int64]]:
        lags = np.arange(self.seq_len)
        q, r = np.broadcast_arrays(qi[:, None, None] - lags, rj[:, None, None] - offsets)  # (M, S, L)
        r_in = np.clip(r, 0, self.n - 1)
        fits = (
            (r >= 0)
            & (r < self.limit[np.clip(q, 0, self.n - 1)])
            & (self.chain[r_in] == self.chain[rj][:, None, None])
        )
        ok = (self.pos[qi] >= self.seq_len - 1)[:, None] & fits.all(axis=2)
        d = np.full(r.shape, np.inf, dtype=np.float32)
        d[ok] = self.cache.fetch(q[ok], r[ok])
        mean = d.mean(axis=2)
        best = np.argmin(mean, axis=1)
        take = np.arange(qi.size)
        hits = (d[take, best] < self.d_hit).sum(axis=1)
        return mean[take, best].astype(np.float32), hits.astype(np.int64)
