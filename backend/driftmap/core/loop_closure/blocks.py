"""The loop-closure search split in three: a global plan, independent query blocks, sequential decisions.

:func:`driftmap.core.loop_closure.search.detect_loops` is

1. :func:`plan_search`, once for all keyframes: the frames' coarse descriptors (their mean and principal
   axes come from the first ``basis_keyframes`` keyframes), the background median and sigma of eq. 3 on
   random pairs among those keyframes, and the thresholds ``d_t`` and ``d_hit``;
2. :func:`score_queries` on each block of query frames ``q0 .. q1 - 1``: coarse candidates, eq. 3 on
   them, the sequence checks of the best ones and of their neighbours (the rivals). A block needs only
   the plan, so blocks can run anywhere (a map build's ``map.loops`` subtasks); their boundaries follow
   the grid of :func:`~driftmap.core.loop_closure.descriptors.query_blocks` (``coarse_block`` queries), so every
   score is computed exactly as in one run over all queries;
3. the decisions, in query order (:mod:`driftmap.core.loop_closure.search`): whether a place is distinctive depends
   on the closures already accepted.

Both results convert to flat arrays (``to_arrays`` / ``from_arrays``) for a blob store.

The plan of a site's keyframes thus depends only on its first ``basis_keyframes`` keyframes, and a
keyframe's descriptor only on its thumbnail and that basis
(:func:`~driftmap.core.loop_closure.descriptors.project` computes each row alike whatever the other rows): a
search over more chains, planned afresh, has the same basis, the same descriptors of the earlier keyframes and
so the same scores for their queries.

A search can resume an earlier one (an incremental map build): when the first chains are those of the earlier
search and hold the keyframes its basis came from, its
:class:`~driftmap.core.loop_closure.resume.SearchBasis` (descriptor mean and axes, the descriptors of those
chains' keyframes, background, thresholds) plans the new one (``plan_search(..., basis=)``), and its query
blocks up to the last edge of the block grid within those chains, the last cut there
(:func:`~driftmap.core.loop_closure.resume.resumable_blocks`), are the new search's blocks too: their queries'
references are all earlier frames, ranked and scored exactly as the new search would. Only the queries after
them are scored (``split_queries(..., start=)``).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields, replace

import numpy as np
from numpy.typing import NDArray

from driftmap.core.loop_closure.descriptors import (
    coarse_candidates,
    descriptor_basis,
    project,
    query_blocks,
    thumbnails,
)
from driftmap.core.loop_closure.pair_scores import DiagonalScorer, PairCache
from driftmap.core.loop_closure.params import LoopParams
from driftmap.core.loop_closure.resume import SearchBasis
from driftmap.core.types import F32, I64

__all__ = [
    "LoopSearch",
    "QueryScores",
    "plan_search",
    "score_queries",
    "split_queries",
]


@dataclass(frozen=True, eq=False)
class LoopSearch:
    """Step 1: what every query block needs.

    Attributes:
        frames: ``(G, H, W)`` float32 pre-processed keyframes of all chains, in global order.
        chain: ``(G,)`` chain of each frame; ``pos``: ``(G,)`` its index in its chain.
        limit: ``(G,)`` exclusive end of each query's eligible references (earlier chains entirely, its
            own chain outside the recent window).
        desc: ``(G, D)`` float32 unit coarse descriptors.
        mean: ``(P,)`` float32 and ``axes`` ``(P, D)`` (or ``(P, 0)``) float32: their basis.
        background: ``(4,)`` float64 median and sigma of d over random eligible pairs, ``d_t``, ``d_hit``.
        n_background: full SAD comparisons of the background sample.
        descriptors_s: seconds the descriptors took.
    """

    frames: F32
    chain: I64
    pos: I64
    limit: I64
    desc: F32
    mean: F32
    axes: F32
    background: NDArray[np.float64]
    n_background: int
    descriptors_s: float

    @property
    def n(self) -> int:
        """Keyframes of all chains."""
        return int(self.chain.size)

    def basis(self) -> SearchBasis:
        """The basis a later search over more chains can resume this one with."""
        return SearchBasis(self.mean, self.axes, self.desc, self.background)

    def to_arrays(self) -> dict[str, NDArray]:
        """Flat arrays (scalars as 0-d) for ``np.savez``."""
        return {f.name: np.asarray(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, NDArray]) -> LoopSearch:
        """Inverse of :meth:`to_arrays`."""
        return cls(
            frames=np.asarray(arrays["frames"], dtype=np.float32),
            chain=np.asarray(arrays["chain"], dtype=np.int64),
            pos=np.asarray(arrays["pos"], dtype=np.int64),
            limit=np.asarray(arrays["limit"], dtype=np.int64),
            desc=np.asarray(arrays["desc"], dtype=np.float32),
            mean=np.asarray(arrays["mean"], dtype=np.float32),
            axes=np.asarray(arrays["axes"], dtype=np.float32),
            background=np.asarray(arrays["background"], dtype=np.float64),
            n_background=int(arrays["n_background"]),
            descriptors_s=float(arrays["descriptors_s"]),
        )


@dataclass(frozen=True, eq=False)
class QueryScores:
    """Step 2 for queries ``q0 .. q0 + Q - 1``: every score their decisions read.

    Attributes:
        q0: global index of the first query.
        checked: ``(Q,)`` bool: some candidate of the query matched well enough to be sequence-checked.
        index: ``(Q, K)`` int64 candidates by ascending d (-1 pads).
        seq: ``(Q, K)`` float32 best mean d of a diagonal ending at the candidate (inf: not checked).
        hits: ``(Q, K)`` int64 frames of that diagonal below ``d_hit``.
        pair: ``(Q, K, 3)`` float32 eq. 3 ``(d, dx, dy)`` of each (query, candidate) pair.
        rivals: ``(M, 2)`` int64 (query, frame) pairs beside the candidates that may close a loop.
        rival_seq: ``(M,)`` float32 and ``rival_hits`` ``(M,)`` int64: their sequence scores.
        rival_pair: ``(M, 3)`` float32 eq. 3 ``(d, dx, dy)`` of the rival pairs.
        counts: ``(3,)`` int64 descriptor products, full SAD comparisons of candidates, of sequences.
        seconds: ``(3,)`` float64 time of the coarse ranking, the candidates' SAD, the sequence checks.
    """

    q0: int
    checked: NDArray[np.bool_]
    index: I64
    seq: F32
    hits: I64
    pair: F32
    rivals: I64
    rival_seq: F32
    rival_hits: I64
    rival_pair: F32
    counts: I64
    seconds: NDArray[np.float64]

    def to_arrays(self) -> dict[str, NDArray]:
        """Flat arrays for ``np.savez``."""
        return {f.name: np.asarray(getattr(self, f.name)) for f in fields(self)}

    @property
    def q1(self) -> int:
        """Global index after the last query."""
        return self.q0 + int(self.checked.size)

    def head(self, q1: int) -> QueryScores:
        """The scores of queries ``q0 .. q1 - 1`` only (every query's scores are its own); the work figures
        (``counts``, ``seconds``) stay the whole block's."""
        if q1 >= self.q1:
            return self
        rows = max(0, q1 - self.q0)
        mine = self.rivals[:, 0] < q1
        return replace(
            self,
            checked=self.checked[:rows],
            index=self.index[:rows],
            seq=self.seq[:rows],
            hits=self.hits[:rows],
            pair=self.pair[:rows],
            rivals=self.rivals[mine],
            rival_seq=self.rival_seq[mine],
            rival_hits=self.rival_hits[mine],
            rival_pair=self.rival_pair[mine],
        )

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, NDArray]) -> QueryScores:
        """Inverse of :meth:`to_arrays`."""
        return cls(
            q0=int(arrays["q0"]),
            checked=np.asarray(arrays["checked"], dtype=np.bool_),
            index=np.asarray(arrays["index"], dtype=np.int64),
            seq=np.asarray(arrays["seq"], dtype=np.float32),
            hits=np.asarray(arrays["hits"], dtype=np.int64),
            pair=np.asarray(arrays["pair"], dtype=np.float32),
            rivals=np.asarray(arrays["rivals"], dtype=np.int64).reshape(-1, 2),
            rival_seq=np.asarray(arrays["rival_seq"], dtype=np.float32),
            rival_hits=np.asarray(arrays["rival_hits"], dtype=np.int64),
            rival_pair=np.asarray(arrays["rival_pair"], dtype=np.float32).reshape(-1, 3),
            counts=np.asarray(arrays["counts"], dtype=np.int64),
            seconds=np.asarray(arrays["seconds"], dtype=np.float64),
        )


def _stack(
    chains: Sequence[NDArray], timestamps_s: Sequence[NDArray] | None, p: LoopParams
) -> tuple[F32, I64, I64, I64]:
    """Validate the input; return frames ``(G, H, W)``, chain ``(G,)``, pos ``(G,)``, limit ``(G,)``."""
    arrays = [np.asarray(c) for c in chains]
    shapes = {a.shape[1:] for a in arrays if a.ndim == 3}
    if any(a.ndim != 3 for a in arrays) or len(shapes) > 1:
        raise ValueError(f"chains must be (N_i, H, W) arrays of one H, W; got {[a.shape for a in arrays]}")
    if timestamps_s is not None and len(timestamps_s) != len(arrays):
        raise ValueError(f"timestamps_s has {len(timestamps_s)} entries for {len(arrays)} chains")
    sizes = [a.shape[0] for a in arrays]
    frames = (
        np.concatenate([a.astype(np.float32, copy=False) for a in arrays]) if arrays else np.zeros((0, 1, 1))
    )
    chain = np.repeat(np.arange(len(arrays), dtype=np.int64), sizes)
    starts = np.concatenate([[0], np.cumsum(sizes)])[:-1].astype(np.int64)
    pos = np.arange(chain.size, dtype=np.int64) - (starts[chain] if chain.size else 0)
    limit = starts[chain] + np.maximum(0, pos - p.recent_frames) if chain.size else pos.copy()
    if timestamps_s is not None:
        for c, t in enumerate(timestamps_s):
            t = np.asarray(t, dtype=np.float64)
            if t.shape != (sizes[c],) or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
                raise ValueError(f"timestamps_s[{c}] must be ({sizes[c]},) finite and non-decreasing")
            n_old = np.searchsorted(t, t - p.recent_s, side="right")
            sl = slice(starts[c], starts[c] + sizes[c])
            limit[sl] = np.minimum(limit[sl], starts[c] + n_old)
    return np.asarray(frames, dtype=np.float32), chain, pos, limit.astype(np.int64)


def plan_search(
    chains: Sequence[NDArray],
    p: LoopParams,
    timestamps_s: Sequence[NDArray] | None = None,
    basis: SearchBasis | None = None,
) -> LoopSearch | None:
    """Step 1 (see the module docstring); None when no frame has an eligible earlier one.

    Args:
        chains: one ``(N_i, H, W)`` float32 stack of pre-processed keyframes per drive, in recording order.
        p: the search parameters.
        timestamps_s: optional ``(N_i,)`` non-decreasing seconds per chain, for ``recent_s``.
        basis: an earlier search's (:meth:`LoopSearch.basis`, or its :meth:`SearchBasis.prefix`), whose
            descriptors are those of these chains' first keyframes: its descriptors, their basis for the other
            keyframes and its thresholds instead of new ones (no background pairs compared).

    Raises:
        ValueError: chains not 3-D or of different image sizes, timestamps of the wrong shape, or a basis
            of other thumbnails or of more keyframes.
    """
    frames, chain, pos, limit = _stack(chains, timestamps_s, p)
    if frames.shape[0] == 0 or limit[-1] == 0:
        return None
    t0 = time.perf_counter()
    if basis is not None:
        known = basis.desc.shape[0]
        if known > frames.shape[0]:
            raise ValueError(
                f"the basis describes {known} keyframes, more than the {frames.shape[0]} searched"
            )
        thumbs = thumbnails(frames[known:], p.coarse_size_px, p.coarse_blur_px)
        mean, axes = basis.mean, basis.axes
        desc = np.concatenate([basis.desc, project(thumbs, mean, axes)])
        t1 = time.perf_counter()
        return LoopSearch(frames, chain, pos, limit, desc, mean, axes, basis.background, 0, t1 - t0)
    thumbs = thumbnails(frames, p.coarse_size_px, p.coarse_blur_px)
    first = min(frames.shape[0], p.basis_keyframes)
    mean, axes = descriptor_basis(thumbs[:first], p.coarse_dims)
    desc = project(thumbs, mean, axes)
    t1 = time.perf_counter()
    cache = PairCache(frames, p.sad)
    eligible = limit[:first] if limit[:first].any() else limit  # (a basis of too few keyframes)
    median, sigma = cache.background(eligible, p.background_pairs, p.seed)
    sigma = max(sigma, p.sigma_floor * median, 1e-3)
    d_t = p.d_t if p.d_t is not None else median - p.d_t_sigmas * sigma
    d_hit = d_t if p.d_t is not None else median - p.hit_sigmas * sigma
    background = np.array([median, sigma, d_t, d_hit], dtype=np.float64)
    return LoopSearch(frames, chain, pos, limit, desc, mean, axes, background, cache.n_computed, t1 - t0)


def split_queries(search: LoopSearch, p: LoopParams, queries: int, start: int = 0) -> list[tuple[int, int]]:
    """Query ranges ``(q0, q1)`` of about ``queries`` frames covering every query from ``start`` (a point of
    the grid of :func:`~driftmap.core.loop_closure.descriptors.query_blocks`, or 0) on, on that grid (whole
    blocks of ``p.coarse_block``)."""
    grid = query_blocks(search.limit, p.coarse_block)
    step = max(1, round(queries / p.coarse_block))
    ahead = grid if start == 0 else [g for g in grid if g >= start]
    cuts = [start, *ahead[step:-1:step], search.n]
    return [(a, b) for a, b in itertools.pairwise(cuts) if b > a]


def score_queries(search: LoopSearch, p: LoopParams, q0: int = 0, q1: int | None = None) -> QueryScores:
    """Step 2 for queries ``q0 .. q1 - 1`` (default: all), which must lie on the block grid.

    Raises:
        ValueError: the range is off the grid of :func:`~driftmap.core.loop_closure.descriptors.query_blocks`.
    """
    q1 = search.n if q1 is None else q1
    _median, _sigma, d_t, d_hit = search.background.tolist()
    t0 = time.perf_counter()
    cand = coarse_candidates(
        search.desc,
        search.limit,
        search.pos,
        top_k=p.top_k,
        top_k_single=p.top_k_single,
        seq_len=p.coarse_seq_len,
        nms_radius=p.nms_radius,
        block=p.coarse_block,
        queries=(q0, q1),
    )
    t1 = time.perf_counter()
    cache = PairCache(search.frames, p.sad)
    valid = cand.index >= 0
    qi = np.broadcast_to(np.arange(q0, q1)[:, None], cand.index.shape)
    d_cand = np.full(cand.index.shape, np.inf, dtype=np.float32)
    d_cand[valid] = cache.fetch(qi[valid], cand.index[valid])
    n_cand = cache.n_computed
    t2 = time.perf_counter()
    # Sequence checks of the lowest-d candidates whose query frame itself matches, in one batch.
    order = np.argsort(d_cand, axis=1, kind="stable")
    d_sorted = np.take_along_axis(d_cand, order, axis=1)
    idx_sorted = np.take_along_axis(cand.index, order, axis=1)
    gate = max(d_t, d_hit)  # the query frame itself must match
    checked = (d_sorted < gate) & (np.arange(d_sorted.shape[1]) < p.max_seq_checks)[None, :]
    diag = DiagonalScorer(
        cache, search.chain, search.pos, search.limit, p.seq_len, p.seq_slopes, (d_hit, d_t, p.seq_min_hits)
    )
    seq = np.full(d_cand.shape, np.inf, dtype=np.float32)
    hits = np.zeros(d_cand.shape, dtype=np.int64)
    seq[checked], hits[checked] = diag.scores(qi[checked], idx_sorted[checked])
    # Rivals: the frames beside every candidate of a query that may close a loop (a coarse peak may
    # be one frame off the true one), checked in a second batch before any decision.
    passing = checked & (seq < d_t) & (hits >= p.seq_min_hits)
    rows = np.flatnonzero(passing.any(axis=1))
    beside = _beside(q0, rows, cand.index, np.where(checked, idx_sorted, -1), search.limit)
    beside = beside[cache.fetch(beside[:, 0], beside[:, 1]) < gate]
    rival_seq, rival_hits = diag.scores(beside[:, 0], beside[:, 1])
    t3 = time.perf_counter()
    return QueryScores(
        q0=q0,
        checked=checked.any(axis=1),
        index=idx_sorted,
        seq=seq,
        hits=hits,
        pair=_pairs(cache, qi, idx_sorted, np.isfinite(seq)),
        rivals=beside,
        rival_seq=rival_seq,
        rival_hits=rival_hits,
        rival_pair=_pairs(cache, beside[:, 0], beside[:, 1], np.isfinite(rival_seq)),
        counts=np.array([cand.n_compared, n_cand, cache.n_computed - n_cand], dtype=np.int64),
        seconds=np.array([t1 - t0, t2 - t1, t3 - t2], dtype=np.float64),
    )


def _pairs(cache: PairCache, qi: NDArray, rj: NDArray, where: NDArray[np.bool_]) -> F32:
    """``qi.shape + (3,)`` float32 ``(d, dx, dy)`` of the pairs ``where`` is true (fetched), else NaN."""
    out = np.full((*np.shape(qi), 3), np.nan, dtype=np.float32)
    for k in zip(*np.nonzero(where), strict=True):
        out[k] = cache.get(int(qi[k]), int(rj[k]))
    return out


def _beside(q0: int, rows: I64, index: I64, known: I64, limit: I64) -> I64:
    """``(M, 2)`` unique (query, frame) pairs: eligible frames next to a query's candidates, not known.

    ``rows`` are rows of the block's ``index`` and ``known`` (query ``q0 + row``)."""
    c = index[rows]
    nb = np.concatenate([c - 1, c + 1], axis=1)
    ok = (np.concatenate([c, c], axis=1) >= 0) & (nb >= 0) & (nb < limit[q0 + rows][:, None])
    ok &= ~(nb[:, :, None] == known[rows][:, None, :]).any(axis=2)
    q = np.broadcast_to((q0 + rows)[:, None], nb.shape)
    return np.unique(np.stack([q[ok], nb[ok]], axis=1).reshape(-1, 2), axis=0).astype(np.int64)
