"""Appearance-only loop closure between the keyframes of a site's drives ([SSLAM], III-A-2).

The paper compares every new frame with every earlier one by the shifted SAD of eq. 3 (frames
pre-processed as in IV-C) and adds a constraint when ``d(i, j) < d_t``. That costs O(N^2) full
comparisons, and in a mine a single frame is easily fooled by tunnels that look alike.
:func:`detect_loops` keeps eq. 3 but

1. ranks all earlier keyframes of a query by a coarse descriptor and keeps a few distinct places
   (:func:`~driftmap.core.loop_closure.descriptors.coarse_candidates`); eq. 3 runs on those only;
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

from driftmap.core.loop_closure.blocks import LoopSearch, QueryScores, plan_search, score_queries
from driftmap.core.loop_closure.params import LOOPS_DEFAULT, LoopParams

__all__ = [
    "LoopMatch",
    "LoopResult",
    "LoopStats",
    "decide_loops",
    "detect_loops",
]

log = logging.getLogger(__name__)


@dataclass(frozen=True, slots=True)
class LoopMatch:
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

    closures: list[LoopMatch]
    stats: LoopStats

    def pairs(self) -> NDArray[np.int64]:
        """``(K, 4)`` int64 rows ``(chain_a, idx_a, chain_b, idx_b)``."""
        rows = [(c.chain_a, c.idx_a, c.chain_b, c.idx_b) for c in self.closures]
        return np.asarray(rows, dtype=np.int64).reshape(-1, 4)


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
    This is :func:`~driftmap.core.loop_closure.blocks.plan_search`, then
    :func:`~driftmap.core.loop_closure.blocks.score_queries` of all queries (or of any split of them, e.g. in
    other processes: the same scores), then :func:`decide_loops`.

    Args:
        chains: one ``(N_i, H, W)`` float32 stack of pre-processed keyframes per drive
            (:func:`driftmap.core.imaging.images.preprocess`), in recording order; ``N_i`` may be 0.
        params: thresholds and search sizes.
        timestamps_s: optional ``(N_i,)`` non-decreasing seconds per chain, for ``recent_s``.

    Returns:
        :class:`LoopResult`: closures ordered by query frame, thresholds and work statistics.

    Raises:
        ValueError: chains not 3-D or of different image sizes, timestamps of the wrong shape,
            or a SAD shift range leaving no overlap.
    """
    search = plan_search(chains, params, timestamps_s)
    if search is None:
        return LoopResult([], LoopStats(n_frames=sum(int(np.shape(c)[0]) for c in chains)))
    return decide_loops(search, [score_queries(search, params)], params)


_Pairs = dict[tuple[int, int], tuple[float, int, int]]  # (query, reference) -> eq. 3 (d, dx, dy)


def decide_loops(
    search: LoopSearch, blocks: Sequence[QueryScores], params: LoopParams = LOOPS_DEFAULT
) -> LoopResult:
    """Step 3: accept closures query by query, in order, from the scores of every query block.

    Args:
        search: the plan the blocks were scored with.
        blocks: :func:`~driftmap.core.loop_closure.blocks.score_queries` of ranges covering all queries once,
            in any order.
        params: the parameters the plan and the blocks used.

    Raises:
        ValueError: the blocks do not cover the queries exactly once.
    """
    p = params
    blocks = sorted(blocks, key=lambda b: b.q0)
    cuts = [0, *(b.q1 for b in blocks)]
    if [b.q0 for b in blocks] != cuts[:-1] or cuts[-1] != search.n:
        raise ValueError(f"query blocks starting at {cuts[:-1]} do not cover the {search.n} queries once")
    t0 = time.perf_counter()
    chain, pos = search.chain, search.pos
    median, sigma, d_t, d_hit = search.background.tolist()
    places_of = _Places(chain, p.same_place_frames)
    closures: list[LoopMatch] = []
    accepted: dict[int, list[int]] = {}
    for b in blocks:
        extra, pairs = _rival_places(b)
        for row in np.flatnonzero(b.checked).tolist():
            g = b.q0 + row
            prev = accepted.get(g - 1, []) if p.track and pos[g] > 0 else []
            places: list[_Place] = []
            for r, s_r, h_r, pair in zip(
                b.index[row].tolist(),
                b.seq[row].tolist(),
                b.hits[row].tolist(),
                b.pair[row].tolist(),
                strict=True,
            ):
                if np.isfinite(s_r):
                    places.append((r, s_r, h_r, any(chain[e] == chain[r] and abs(e - r) <= 2 for e in prev)))
                    pairs[g, r] = (pair[0], int(pair[1]), int(pair[2]))
            state = (pairs, places_of, pos)
            emitted = _decide(g, places + extra.get(g, []), state, p, (d_t, median), closures)
            if emitted:
                accepted[g] = emitted
    counts = np.sum([b.counts for b in blocks], axis=0)
    seconds = np.sum([b.seconds for b in blocks], axis=0)
    stats = LoopStats(
        n_frames=search.n,
        n_eligible_pairs=int(search.limit.sum()),
        n_coarse=int(counts[0]),
        n_full_background=search.n_background,
        n_full_candidates=int(counts[1]),
        n_full_sequence=int(counts[2]),
        n_sequence_checks=sum(int(np.isfinite(b.seq).sum()) + b.rivals.shape[0] for b in blocks),
        background_median=median,
        background_sigma=sigma,
        d_t=d_t,
        d_hit=d_hit,
        time_s={
            "descriptors": search.descriptors_s,
            "coarse": float(seconds[0]),
            "full": float(seconds[1]),
            "sequence": float(seconds[2]) + time.perf_counter() - t0,
        },
    )
    log.debug("loop closure: %d frames, %d closures, %s", search.n, len(closures), stats)
    return LoopResult(closures, stats)


def _rival_places(block: QueryScores) -> tuple[dict[int, list[_Place]], _Pairs]:
    """The block's sequence-checked rivals as places per query, and their eq. 3 results."""
    extra: dict[int, list[_Place]] = {}
    pairs: _Pairs = {}
    rows = zip(
        block.rivals.tolist(), block.rival_seq.tolist(), block.rival_hits.tolist(), block.rival_pair.tolist(),
        strict=True,
    )  # fmt: skip
    for (g, x), s_x, h_x, pair in rows:
        if np.isfinite(s_x):
            extra.setdefault(g, []).append((x, s_x, h_x, False))
            pairs[g, x] = (pair[0], int(pair[1]), int(pair[2]))
    return extra, pairs


def _decide(
    g: int,
    places: list[_Place],
    state: tuple[_Pairs, _Places, NDArray[np.int64]],
    p: LoopParams,
    thresholds: tuple[float, float],
    out: list[LoopMatch],
) -> list[int]:
    """Accept the distinctive, sequence-consistent places of query ``g``; append closures to ``out``."""
    pairs, m, pos = state
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
        d, dx, dy = pairs[g, r]
        conf_d = min(1.0, max(0.0, (d_t - score) / max(median - d_t, 1e-6)))
        conf_u = 0.5 if tracked else max(0.0, 1.0 - ratio / p.uniqueness_ratio)
        conf = float(np.sqrt(conf_d * conf_u))
        out.append(
            LoopMatch(
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
