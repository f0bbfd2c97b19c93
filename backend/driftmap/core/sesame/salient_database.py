"""SESAME's BuildSalientDatabase ([SESAME] Algorithm 1): keep the most salient frame of each unique view.

Frames are visited in order. A frame nearer than ``A_th`` to a kept frame whose masked SAD (eq. 6, the
incoming frame as the query with its salient mask) is below ``V_th`` shows the same view: it replaces that
kept frame when it is more salient and is dropped otherwise. A frame of a new view is kept when its salient
fraction ``SS / SS_m`` exceeds ``S_th``.

The map build runs the algorithm on every node's frames (:mod:`driftmap.core.topomap.database`). Within one
group of frames the visit is sequential, since each frame is compared with the frames kept so far, but groups
are independent: :func:`build_salient_databases` steps all groups in lockstep and scores the comparisons of
each step in one :func:`~driftmap.core.imaging.sad.sad_pairs` call, so a few comparisons per frame cost a
share of one pass over the shifts instead of a pass each. A pair's score depends only on the two frames'
thumbnails and the query's mask, not on where the frames lie, so a :class:`PairScores` handed in answers
the pairs an earlier run scored (an incremental map build scores only pairs it has not seen) and records
every pair the run compared.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.params import SAD_DEFAULT, SadParams
from driftmap.core.imaging.sad import sad_one_to_many, sad_pairs
from driftmap.core.sesame.masks import SESAME_DEFAULT, SesameParams
from driftmap.core.types import F32, F64, I64, BoolArr
from driftmap.errors import BadInputError

__all__ = ["PairScores", "build_salient_database", "build_salient_databases", "masked_sad"]


class PairScores:
    """Masked SAD scores (eq. 6) of ``(query, reference)`` frame pairs, by flat frame index.

    Built from an earlier run's pairs (all three arrays, or none), it answers :meth:`lookup` for those
    pairs; :meth:`record` adds new ones. :meth:`arrays` gives the pairs looked up or recorded since it was
    built: the ones a run used, which is what the next run is worth being handed.

    Args:
        query: ``(P,)`` int64 flat index of each pair's query frame.
        ref: ``(P,)`` int64 flat index of its reference frame.
        d: ``(P,)`` float32 score (``inf`` where no salient pixel overlaps).
    """

    def __init__(self, query: I64 | None = None, ref: I64 | None = None, d: F32 | None = None) -> None:
        q = np.asarray(query if query is not None else [], dtype=np.int64)
        r = np.asarray(ref if ref is not None else [], dtype=np.int64)
        s = np.asarray(d if d is not None else [], dtype=np.float32)
        if q.ndim != 1 or q.shape != r.shape or q.shape != s.shape:
            raise BadInputError(f"need query, ref, d (P,); got {q.shape}, {r.shape}, {s.shape}", field="d")
        self._known: dict[tuple[int, int], float] = dict(
            zip(zip(q.tolist(), r.tolist(), strict=True), s.tolist(), strict=True)
        )
        self._used: dict[tuple[int, int], float] = {}
        self.reused = 0  # lookups answered
        self.scored = 0  # pairs recorded

    def lookup(self, query: list[int], ref: list[int]) -> list[float | None]:
        """Per pair, its known score or None."""
        out = []
        for pair in zip(query, ref, strict=True):
            d = self._known.get(pair)
            if d is not None:
                self._used[pair] = d
                self.reused += 1
            out.append(d)
        return out

    def record(self, query: list[int], ref: list[int], d: list[float]) -> None:
        """Add the scores of newly scored pairs."""
        for pair, score in zip(zip(query, ref, strict=True), d, strict=True):
            self._known[pair] = self._used[pair] = score
        self.scored += len(d)

    def arrays(self) -> tuple[I64, I64, F32]:
        """``(query, ref, d)`` of the pairs used since construction, ``(P,)`` each, sorted by pair."""
        pairs = sorted(self._used)
        q = np.array([a for a, _b in pairs], dtype=np.int64)
        r = np.array([b for _a, b in pairs], dtype=np.int64)
        return q, r, np.array([self._used[p] for p in pairs], dtype=np.float32)


def masked_sad(
    query: NDArray[np.float32],
    refs: NDArray[np.float32],
    query_mask: BoolArr | None,
    sad_params: SadParams = SAD_DEFAULT,
) -> NDArray[np.float32]:
    """Masked, shift-minimised SAD (eq. 6) of one thumbnail against many; thin wrapper of ``sad_one_to_many``.

    Args:
        query: ``(h, w)`` patch-normalised float32 thumbnail.
        refs: ``(M, h, w)`` thumbnails.
        query_mask: bool ``(h, w)`` salient mask of the query, or None for the plain SAD.
        sad_params: shift ranges.

    Returns:
        float32 ``(M,)``: mean absolute difference over the salient overlap at the best shift (``inf``
        where no salient pixel overlaps).
    """
    mask = None if query_mask is None else np.asarray(query_mask, dtype=np.float32)
    return sad_one_to_many(query, refs, sad_params, mask=mask).d


def build_salient_database(
    xy_m: F64,
    saliency: F64,
    thumbs: NDArray[np.float32],
    masks: BoolArr | None,
    params: SesameParams = SESAME_DEFAULT,
    sad_params: SadParams = SAD_DEFAULT,
) -> I64:
    """Algorithm 1 on one group of frames, visited in input order (see the module docstring).

    Args:
        xy_m: ``(C, 2)`` float64 frame positions, metres.
        saliency: ``(C,)`` float64 ``SS / SS_m`` of each frame, fraction in [0, 1].
        thumbs: ``(C, h, w)`` float32 patch-normalised thumbnails.
        masks: bool ``(C, h, w)`` salient masks of the thumbnails, or None (plain SAD).
        params: ``adjacency_m``, ``similarity``, ``saliency_min``, ``use_mask``.
        sad_params: shift ranges of the SAD.

    Returns:
        int64 ``(U,)`` positions of the kept frames in input order of first admission.
    """
    c = np.shape(saliency)[0] if np.ndim(saliency) == 1 else -1
    if np.shape(xy_m) != (c, 2):
        raise BadInputError(f"need xy (C, 2) and saliency (C,); got {np.shape(xy_m)}, {np.shape(saliency)}")
    group = np.arange(c, dtype=np.int64)
    return build_salient_databases([group], [xy_m], saliency, thumbs, masks, params, sad_params)[0]


def build_salient_databases(
    frames: Sequence[I64],
    xy_m: Sequence[F64],
    saliency: F64,
    thumbs: NDArray[np.float32],
    masks: BoolArr | None,
    params: SesameParams = SESAME_DEFAULT,
    sad_params: SadParams = SAD_DEFAULT,
    scores: PairScores | None = None,
) -> list[I64]:
    """Algorithm 1 on many independent groups of frames at once, each as :func:`build_salient_database`.

    Args:
        frames: per group, ``(C_g,)`` int64 indices of its frames into the per-frame arrays, in the order
            they are visited.
        xy_m: per group, ``(C_g, 2)`` float64 positions of those frames, metres.
        saliency: ``(F,)`` float64 ``SS / SS_m`` of every frame, fraction in [0, 1].
        thumbs: ``(F, h, w)`` float32 patch-normalised thumbnails.
        masks: bool ``(F, h, w)`` salient masks of the thumbnails, or None (plain SAD).
        params: ``adjacency_m``, ``similarity``, ``saliency_min``, ``use_mask``.
        sad_params: shift ranges of the SAD.

    Returns:
        Per group, int64 ``(U_g,)`` positions (into the group) of its kept frames, in order of first
        admission.

    Raises:
        BadInputError: the groups or per-frame arrays disagree in shape, or an index is out of range.
    """
    sal = np.asarray(saliency, dtype=np.float64)
    th = np.asarray(thumbs, dtype=np.float32)
    n = sal.shape[0] if sal.ndim == 1 else -1
    if th.ndim != 3 or th.shape[0] != n or (masks is not None and np.shape(masks) != th.shape):
        raise BadInputError(
            f"need saliency (F,), thumbs and masks (F, h, w); got {sal.shape}, {th.shape}", field="thumbs"
        )
    index = [np.asarray(f, dtype=np.int64) for f in frames]
    points = [np.asarray(p, dtype=np.float64) for p in xy_m]
    for g, (f, p) in enumerate(zip(index, points, strict=True)):
        if f.ndim != 1 or p.shape != (f.size, 2) or (f.size and (f.min() < 0 or f.max() >= n)):
            raise BadInputError(
                f"group {g}: frames (C,) in 0..{n - 1} and xy (C, 2) expected", field="frames"
            )
    weights = masks if masks is not None and params.use_mask else None
    xy = [p.tolist() for p in points]
    kept: list[list[int]] = [[] for _ in index]  # per group, positions of its kept frames
    sizes = np.array([f.size for f in index], dtype=np.int64)
    longest_first = np.argsort(-sizes, kind="stable").tolist()
    for step in range(int(sizes.max(initial=0))):
        waiting: list[tuple[int, list[int]]] = []  # (group, the kept positions near its frame)
        qi: list[int] = []
        rj: list[int] = []
        for g in longest_first[: int(np.count_nonzero(sizes > step))]:
            f = index[g]
            x, y = xy[g][step]
            near = [u for u in kept[g] if math.hypot(x - xy[g][u][0], y - xy[g][u][1]) < params.adjacency_m]
            if near:
                waiting.append((g, near))
                qi.extend([int(f[step])] * len(near))
                rj.extend(int(f[u]) for u in near)
            elif sal[f[step]] > params.saliency_min:
                kept[g].append(step)
        if not waiting:
            continue
        d = _pair_scores(th, qi, rj, sad_params, weights, scores)
        at = 0
        for g, near in waiting:
            f, s = index[g], sal[index[g][step]]
            near_d = d[at : at + len(near)]
            at += len(near)
            same = next((u for u, dist in zip(near, near_d, strict=True) if dist < params.similarity), None)
            if same is None:
                if s > params.saliency_min:
                    kept[g].append(step)
            elif s > sal[f[same]]:
                kept[g][kept[g].index(same)] = step
    return [np.asarray(k, dtype=np.int64) for k in kept]


def _pair_scores(
    thumbs: NDArray[np.float32],
    qi: list[int],
    rj: list[int],
    sad_params: SadParams,
    weights: BoolArr | None,
    scores: PairScores | None,
) -> list[float]:
    """Masked SAD of pairs ``(thumbs[qi[p]], thumbs[rj[p]])``, those ``scores`` knows taken from it."""
    if scores is None:
        scored: list[float] = sad_pairs(
            thumbs, np.asarray(qi), np.asarray(rj), sad_params, weights
        ).d.tolist()
        return scored
    known = scores.lookup(qi, rj)
    todo = [p for p, d in enumerate(known) if d is None]
    if todo:
        q, r = [qi[p] for p in todo], [rj[p] for p in todo]
        new: list[float] = sad_pairs(thumbs, np.asarray(q), np.asarray(r), sad_params, weights).d.tolist()
        scores.record(q, r, new)
        for p, score in zip(todo, new, strict=True):
            known[p] = score
    return [float(d) for d in known if d is not None]
