"""Appearance-only loop closure between the keyframes of a site's drives (paper 000, III-A-2).

The paper compares every new frame with every earlier one by the shifted SAD of eq. 3 (frames
pre-processed as in IV-C) and adds a constraint when ``d(i, j) < d_t``. That costs O(N^2) full
comparisons, and in a mine a single frame is easily fooled by tunnels that look alike.
:func:`detect_loops` keeps eq. 3 but

1. ranks all earlier keyframes of a query by a coarse descriptor and keeps a few distinct places
   (:func:`~driftmap.core.descriptors.coarse_candidates`); eq. 3 runs on those only;
2. accepts ``(i, j)`` only when ``d(i, j) < d_hit`` and a *sequence* of ``seq_len`` query frames
   ``i - l`` matches reference frames ``j - round(v l)`` for one of a few slopes ``v`` (SeqSLAM's
   diagonal): mean d below d_t, at least ``seq_min_hits`` frames below d_hit. Negative slopes match
   a pass with the same heading travelled backwards (an LHD reversing out of a drawpoint sees the
   same view); opposite headings are not matched (a forward camera sees another view);
3. requires the match to be *distinctive*: the best other place's margin below the background
   median, over this match's margin, at most ``uniqueness_ratio``. Frames within
   ``same_place_frames`` of one chain, or linked by an accepted closure, are one place (a third pass
   matching two earlier ones is not ambiguous). A place continuing the previous query frame's
   closure (+-2 frames) needs no uniqueness unless another place is clearly better: tracking
   through an aliased stretch entered at a distinctive place.

Thresholds. d is dimensionless (patch-normalised pixels), but unrelated views score ~1.0 on random
texture and ~0.73 +- 0.05 in one mine's tunnels, whose views share their layout; revisits score
0.3-0.7. No fixed d_t suits both, so by default the thresholds are relative to the background: eq. 3
on ``background_pairs`` random eligible pairs (nearly all unrelated) gives a median m and a robust
sigma s (1.4826 MAD, at least ``sigma_floor`` m); ``d_t = m - d_t_sigmas s`` and
``d_hit = m - hit_sigmas s``. An absolute ``d_t`` (the paper's rule) can be given instead; then
``d_hit = d_t``. :class:`LoopStats` reports the values used.

Pose of a closure: appearance gives no metric relative pose. Add it as ~ identity (same place, same
heading) with the suggested ``sigma_xy_m``, a few metres (keyframe spacing, the +-1 frame
uncertainty, the lateral position in the tunnel), and ``sigma_theta_rad``. ``shift_px`` (query pixel
``(x, y)`` matches reference pixel ``(x + dx, y + dy)``) hints at a yaw and lateral offset.

Frames are addressed by ``(chain, index)``; the global order is chain 0, then chain 1, ... (pass
chains in recording order). Decisions are causal except that the descriptor mean and PCA axes and
the background use all frames.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from driftmap.core.descriptors import DiagonalScorer, PairCache, coarse_candidates, describe, thumbnails
from driftmap.core.params import SAD_DEFAULT, SAD_FAST, SadParams

__all__ = [
    "LOOPS_DEFAULT",
    "LOOPS_FAST",
    "LOOPS_PAPER",
    "LoopClosure",
    "LoopParams",
    "LoopResult",
    "LoopStats",
    "detect_loops",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class LoopParams:
    """Loop closure by shifted SAD (paper 000 III-A-2, eq. 3) with candidates and sequence checks."""

    d_t: float | None = None  # absolute eq. 3 threshold on a sequence's mean d; None: from the background
    d_t_sigmas: float = 4.5  # relative d_t = background median - this x background sigma
    hit_sigmas: float = 3.0  # relative d_hit (a matching frame of a sequence), same form
    sigma_floor: float = 0.05  # background sigma used is at least this fraction of its median
    background_pairs: int = 2000  # random eligible pairs scored for the background median and sigma
    sad: SadParams = SAD_DEFAULT  # shift search +-x_max, +-y_max of eq. 3, pixels of the frames
    recent_frames: int = 20  # same-chain frames i-1 .. i-recent_frames are never compared with i
    recent_s: float = 0.0  # also exclude same-chain frames less than this many seconds older
    coarse_size_px: tuple[int, int] = (16, 8)  # (width, height) of the coarse thumbnail descriptor
    coarse_blur_px: float = 3.0  # Gaussian sigma before thumbnailing, frame pixels (shift tolerance)
    coarse_dims: int = 64  # PCA dimensions of the centred thumbnail; 0 keeps all
    coarse_seq_len: int = 5  # frames averaged along the diagonal of the coarse similarity
    top_k: int = 4  # distinct-place candidates per query by sequence-filtered descriptors, full SAD
    top_k_single: int = 4  # plus this many by single-frame descriptors (revisit starts, turns)
    nms_radius: int = 2  # a coarse candidate is the best within this many frames of its chain
    seq_len: int = 5  # query frames i-seq_len+1 .. i that must match a diagonal; 1 = single frame
    seq_min_hits: int = 4  # of those, frames that must have d < d_hit
    seq_slopes: tuple[float, ...] = (-1.5, -1, -0.67, 0.67, 1, 1.5)  # ref./query frames; < 0 reversing
    max_seq_checks: int = 3  # candidates per query with d < d_hit whose sequences are checked
    uniqueness_ratio: float = 0.7  # accept when other place's margin / this margin <= this; 1 = off
    same_place_frames: int = 4  # same-chain frames this close (or linked by a closure) are one place
    track: bool = True  # continuing the previous frame's closure needs no uniqueness test
    max_closures_per_query: int = 2  # closures emitted per query frame (to distinct places)
    sigma_xy_m: float = 2.0  # suggested position sigma of a confident closure, metres
    sigma_xy_max_m: float = 6.0  # ... of a closure at the limits of the tests, metres
    sigma_theta_rad: float = 0.2  # suggested heading sigma (same-direction passes), radians
    seed: int = 0  # of the background pair sample

    def __post_init__(self) -> None:
        if self.d_t is not None and not self.d_t > 0:
            raise ValueError(f"LoopParams.d_t must be > 0 or None, got {self.d_t}")
        nonneg = (
            "recent_frames",
            "recent_s",
            "coarse_dims",
            "nms_radius",
            "same_place_frames",
            "top_k_single",
        )
        for name in nonneg:
            if getattr(self, name) < 0:
                raise ValueError(f"LoopParams.{name} must be >= 0, got {getattr(self, name)}")
        for name in ("top_k", "seq_len", "coarse_seq_len", "max_seq_checks", "max_closures_per_query"):
            if getattr(self, name) < 1:
                raise ValueError(f"LoopParams.{name} must be >= 1, got {getattr(self, name)}")
        if not 1 <= self.seq_min_hits <= self.seq_len:
            raise ValueError("LoopParams.seq_min_hits must be in 1 .. seq_len")
        if not self.seq_slopes or 0 in self.seq_slopes:
            raise ValueError("LoopParams.seq_slopes must be non-empty and non-zero")
        if not 0 < self.uniqueness_ratio <= 1 or self.background_pairs < 10:
            raise ValueError("LoopParams: 0 < uniqueness_ratio <= 1 and background_pairs >= 10")
        if min(self.coarse_size_px) <= 0 or not 0 < self.sigma_xy_m <= self.sigma_xy_max_m:
            raise ValueError("LoopParams: coarse_size_px > 0 and 0 < sigma_xy_m <= sigma_xy_max_m")


LOOPS_DEFAULT = LoopParams()
# The paper's rule: the best earlier frame with d < d_t, no sequence or uniqueness test (aliasing-prone).
LOOPS_PAPER = LoopParams(
    coarse_seq_len=1,
    top_k=8,
    seq_len=1,
    seq_min_hits=1,
    uniqueness_ratio=1.0,
    track=False,
    max_closures_per_query=1,
)
LOOPS_FAST = LoopParams(
    sad=SAD_FAST, coarse_dims=32, top_k=3, top_k_single=2, max_seq_checks=2, background_pairs=500
)


@dataclass(frozen=True, slots=True)
class LoopClosure:
    """Query frame ``(chain_a, idx_a)`` shows the place of the earlier ``(chain_b, idx_b)``.

    Relative pose: ~ identity with the suggested sigmas (see the module docstring).

    Attributes:
        chain_a: chain of the query frame.
        idx_a: index of the query frame in its chain.
        chain_b: chain of the matched reference frame.
        idx_b: index of the reference frame in its chain.
        d: eq. 3 score of the pair (mean absolute difference of patch-normalised pixels).
        seq_d: mean d along the accepted diagonal of ``seq_len`` frame pairs.
        uniqueness: best other place's margin below the background / this one's (0: no rival).
        shift_px: ``(dx, dy)`` best SAD shift of the pair, pixels of the compared frames.
        confidence: in [0, 1], from the margins below d_t and of the uniqueness test.
        sigma_xy_m: suggested position sigma of the constraint, metres.
        sigma_theta_rad: suggested heading sigma, radians.
        tracked: accepted as the continuation of the previous query frame's closure.
    """

    chain_a: int
    idx_a: int
    chain_b: int
    idx_b: int
    d: float
    seq_d: float
    uniqueness: float
    shift_px: tuple[int, int]
    confidence: float
    sigma_xy_m: float
    sigma_theta_rad: float
    tracked: bool


@dataclass(frozen=True)
class LoopStats:
    """Thresholds used and work done by :func:`detect_loops`.

    Attributes:
        n_frames: frames of all chains.
        n_eligible_pairs: (query, earlier frame) pairs outside the recent window: the full search.
        n_coarse: descriptor similarities computed.
        n_full_background: full SAD comparisons of the background sample.
        n_full_candidates: full SAD comparisons of queries against their coarse candidates.
        n_full_sequence: further full SAD comparisons made by the sequence checks.
        n_sequence_checks: diagonals evaluated.
        background_median: median d of random eligible pairs.
        background_sigma: their robust standard deviation (1.4826 MAD), at least ``sigma_floor`` x median.
        d_t: threshold on a sequence's mean d that was applied.
        d_hit: per-frame threshold that was applied.
        time_s: seconds per stage: ``descriptors``, ``coarse``, ``full``, ``sequence``.
    """

    n_frames: int = 0
    n_eligible_pairs: int = 0
    n_coarse: int = 0
    n_full_background: int = 0
    n_full_candidates: int = 0
    n_full_sequence: int = 0
    n_sequence_checks: int = 0
    background_median: float = float("nan")
    background_sigma: float = float("nan")
    d_t: float = float("nan")
    d_hit: float = float("nan")
    time_s: dict[str, float] = field(default_factory=dict)

    @property
    def n_full(self) -> int:
        """All full shifted-SAD comparisons."""
        return self.n_full_background + self.n_full_candidates + self.n_full_sequence


@dataclass(frozen=True)
class LoopResult:
    """Closures in query order, plus thresholds and work statistics."""

    closures: list[LoopClosure]
    stats: LoopStats

    def pairs(self) -> NDArray[np.int64]:
        """``(K, 4)`` int64 rows ``(chain_a, idx_a, chain_b, idx_b)``."""
        rows = [(c.chain_a, c.idx_a, c.chain_b, c.idx_b) for c in self.closures]
        return np.asarray(rows, dtype=np.int64).reshape(-1, 4)


def _stack(
    chains: Sequence[NDArray], timestamps_s: Sequence[NDArray] | None, params: LoopParams
) -> tuple[NDArray[np.float32], NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]:
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
    limit = starts[chain] + np.maximum(0, pos - params.recent_frames) if chain.size else pos.copy()
    if timestamps_s is not None:
        for c, t in enumerate(timestamps_s):
            t = np.asarray(t, dtype=np.float64)
            if t.shape != (sizes[c],) or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
                raise ValueError(f"timestamps_s[{c}] must be ({sizes[c]},) finite and non-decreasing")
            n_old = np.searchsorted(t, t - params.recent_s, side="right")
            sl = slice(starts[c], starts[c] + sizes[c])
            limit[sl] = np.minimum(limit[sl], starts[c] + n_old)
    return np.asarray(frames, dtype=np.float32), chain, pos, limit.astype(np.int64)


_Place = tuple[int, float, int, bool]  # a sequence-checked place: (reference, score, hits, tracked)


class _Places:
    """Which frames count as one place: one chain within ``radius`` frames, or linked by a closure."""

    def __init__(self, chain: NDArray[np.int64], radius: int) -> None:
        self.chain, self.radius, self.n = chain, radius, chain.size
        self.links: dict[int, list[int]] = {}

    def same_place(self, a: int, b: int) -> bool:
        """Frames ``a`` and ``b`` are one place."""
        rad, ch = self.radius, self.chain
        if ch[a] == ch[b] and abs(a - b) <= rad:
            return True
        for x in range(max(0, a - rad), min(self.n, a + rad + 1)):
            if ch[x] == ch[a]:
                for y in self.links.get(x, ()):
                    if ch[y] == ch[b] and abs(y - b) <= rad:
                        return True
        return False

    def link(self, a: int, b: int) -> None:
        self.links.setdefault(a, []).append(b)
        self.links.setdefault(b, []).append(a)


def detect_loops(
    chains: Sequence[NDArray],
    params: LoopParams = LOOPS_DEFAULT,
    timestamps_s: Sequence[NDArray] | None = None,
) -> LoopResult:
    """Find loop closures among the keyframes of a site's mapping drives (see the module docstring).

    Every keyframe is compared with every earlier keyframe in the global order (all frames of
    earlier chains; its own chain outside the recent window) through the coarse candidate search.

    Args:
        chains: one ``(N_i, H, W)`` float32 stack of pre-processed keyframes per drive
            (:func:`driftmap.core.images.preprocess`), in recording order; ``N_i`` may be 0.
        params: thresholds and search sizes.
        timestamps_s: optional ``(N_i,)`` non-decreasing seconds per chain, for ``recent_s``.

    Returns:
        :class:`LoopResult`: closures ordered by query frame, thresholds and work statistics.

    Raises:
        ValueError: chains not 3-D or of different image sizes, timestamps of the wrong shape,
            or a SAD shift range leaving no overlap.
    """
    p = params
    frames, chain, pos, limit = _stack(chains, timestamps_s, p)
    n = frames.shape[0]
    if n == 0 or limit[-1] == 0:
        return LoopResult([], LoopStats(n_frames=n))
    t0 = time.perf_counter()
    desc = describe(thumbnails(frames, p.coarse_size_px, p.coarse_blur_px), p.coarse_dims)
    t1 = time.perf_counter()
    cand = coarse_candidates(
        desc,
        limit,
        pos,
        top_k=p.top_k,
        top_k_single=p.top_k_single,
        seq_len=p.coarse_seq_len,
        nms_radius=p.nms_radius,
    )
    t2 = time.perf_counter()
    cache = PairCache(frames, p.sad)
    median, sigma = cache.background(limit, p.background_pairs, p.seed)
    sigma = max(sigma, p.sigma_floor * median, 1e-3)
    n_bg = cache.n_computed
    d_t = p.d_t if p.d_t is not None else median - p.d_t_sigmas * sigma
    d_hit = d_t if p.d_t is not None else median - p.hit_sigmas * sigma
    valid = cand.index >= 0
    qi = np.broadcast_to(np.arange(n)[:, None], cand.index.shape)
    d_cand = np.full(cand.index.shape, np.inf, dtype=np.float32)
    d_cand[valid] = cache.fetch(qi[valid], cand.index[valid])
    n_cand = cache.n_computed - n_bg
    t3 = time.perf_counter()
    # Sequence checks of the lowest-d candidates whose query frame itself matches, in one batch.
    order = np.argsort(d_cand, axis=1, kind="stable")
    d_sorted = np.take_along_axis(d_cand, order, axis=1)
    idx_sorted = np.take_along_axis(cand.index, order, axis=1)
    gate = max(d_t, d_hit)  # the query frame itself must match
    checked = (d_sorted < gate) & (np.arange(d_sorted.shape[1]) < p.max_seq_checks)[None, :]
    diag = DiagonalScorer(cache, chain, pos, limit, p.seq_len, p.seq_slopes, (d_hit, d_t, p.seq_min_hits))
    places_of = _Places(chain, p.same_place_frames)
    seq = np.full(d_cand.shape, np.inf, dtype=np.float32)
    hits = np.zeros(d_cand.shape, dtype=np.int64)
    seq[checked], hits[checked] = diag.scores(qi[checked], idx_sorted[checked])
    # Rivals: the frames beside every candidate of a query that may close a loop (a coarse peak may
    # be one frame off the true one), checked in a second batch before any decision.
    passing = checked & (seq < d_t) & (hits >= p.seq_min_hits)
    beside = _beside(
        np.flatnonzero(passing.any(axis=1)), cand.index, np.where(checked, idx_sorted, -1), limit
    )
    beside = beside[cache.fetch(beside[:, 0], beside[:, 1]) < gate]
    rival_seq, rival_hits = diag.scores(beside[:, 0], beside[:, 1])
    n_checks = int(checked.sum()) + len(beside)
    extra: dict[int, list[_Place]] = {}
    for (g, x), s_x, h_x in zip(beside.tolist(), rival_seq.tolist(), rival_hits.tolist(), strict=True):
        if np.isfinite(s_x):
            extra.setdefault(g, []).append((x, s_x, h_x, False))
    closures: list[LoopClosure] = []
    accepted: dict[int, list[int]] = {}
    for g in np.flatnonzero(checked.any(axis=1)).tolist():
        prev = accepted.get(g - 1, []) if p.track and pos[g] > 0 else []
        places: list[_Place] = [
            (r, s_r, h_r, any(chain[e] == chain[r] and abs(e - r) <= 2 for e in prev))
            for r, s_r, h_r in zip(idx_sorted[g].tolist(), seq[g].tolist(), hits[g].tolist(), strict=True)
            if np.isfinite(s_r)
        ]
        emitted = _decide(g, places + extra.get(g, []), (cache, places_of, pos), p, (d_t, median), closures)
        if emitted:
            accepted[g] = emitted
    t4 = time.perf_counter()
    stats = LoopStats(
        n_frames=n,
        n_eligible_pairs=int(limit.sum()),
        n_coarse=cand.n_compared,
        n_full_background=n_bg,
        n_full_candidates=n_cand,
        n_full_sequence=cache.n_computed - n_bg - n_cand,
        n_sequence_checks=n_checks,
        background_median=median,
        background_sigma=sigma,
        d_t=d_t,
        d_hit=d_hit,
        time_s={"descriptors": t1 - t0, "coarse": t2 - t1, "full": t3 - t2, "sequence": t4 - t3},
    )
    log.debug("loop closure: %d frames, %d closures, %s", n, len(closures), stats)
    return LoopResult(closures, stats)


def _beside(
    queries: NDArray[np.int64], index: NDArray[np.int64], known: NDArray[np.int64], limit: NDArray[np.int64]
) -> NDArray[np.int64]:
    """``(M, 2)`` unique (query, frame) pairs: eligible frames next to a query's candidates, not known."""
    c = index[queries]
    nb = np.concatenate([c - 1, c + 1], axis=1)
    ok = (np.concatenate([c, c], axis=1) >= 0) & (nb >= 0) & (nb < limit[queries][:, None])
    ok &= ~(nb[:, :, None] == known[queries][:, None, :]).any(axis=2)
    q = np.broadcast_to(queries[:, None], nb.shape)
    return np.unique(np.stack([q[ok], nb[ok]], axis=1).reshape(-1, 2), axis=0).astype(np.int64)


def _decide(
    g: int,
    places: list[_Place],
    state: tuple[PairCache, _Places, NDArray[np.int64]],
    p: LoopParams,
    thresholds: tuple[float, float],
    out: list[LoopClosure],
) -> list[int]:
    """Accept the distinctive, sequence-consistent places of query ``g``; append closures to ``out``."""
    cache, m, pos = state
    d_t, median = thresholds
    emitted: list[int] = []
    for r, score, n_hits, tracked in sorted(places, key=lambda x: x[1]):
        if len(emitted) >= p.max_closures_per_query:
            break
        if not (score < d_t and n_hits >= p.seq_min_hits):
            continue
        if any(m.chain[e] == m.chain[r] and abs(e - r) <= m.radius for e in emitted):
            continue
        rival = max((median - s for x, s, _, _ in places if not m.same_place(r, x)), default=0.0)
        ratio = max(rival, 0.0) / max(median - score, 1e-6)
        if ratio > (1.0 / p.uniqueness_ratio if tracked else p.uniqueness_ratio):
            continue
        d, dx, dy = cache.get(g, r)
        conf_d = min(1.0, max(0.0, (d_t - score) / max(median - d_t, 1e-6)))
        conf_u = 0.5 if tracked else max(0.0, 1.0 - ratio / p.uniqueness_ratio)
        conf = float(np.sqrt(conf_d * conf_u))
        out.append(
            LoopClosure(
                chain_a=int(m.chain[g]),
                idx_a=int(pos[g]),
                chain_b=int(m.chain[r]),
                idx_b=int(pos[r]),
                d=float(d),
                seq_d=score,
                uniqueness=float(ratio),
                shift_px=(int(dx), int(dy)),
                confidence=conf,
                sigma_xy_m=p.sigma_xy_m + (p.sigma_xy_max_m - p.sigma_xy_m) * (1.0 - conf),
                sigma_theta_rad=p.sigma_theta_rad,
                tracked=tracked,
            )
        )
        m.link(g, r)
        emitted.append(r)
    return emitted
