"""Resuming an earlier loop-closure search over the chains a later one shares with it.

A later search over more chains (an incremental map build) is planned in the earlier search's
:class:`SearchBasis` (:func:`driftmap.core.loop_closure.blocks.plan_search` with ``basis=``); its queries in
the shared chains then have the same references, candidates and scores, so the earlier query blocks up to the
last edge of the block grid within those chains are taken as they are (:func:`resumable_blocks`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from driftmap.core.loop_closure.descriptors import query_blocks
from driftmap.core.loop_closure.params import LoopParams
from driftmap.core.types import F32

if TYPE_CHECKING:
    from driftmap.core.loop_closure.blocks import LoopSearch, QueryScores

__all__ = ["SearchBasis", "resumable_blocks"]


@dataclass(frozen=True, eq=False)
class SearchBasis:
    """What a search's scores depend on besides the frames: the descriptors' basis and the thresholds.

    Attributes:
        mean: ``(P,)`` float32 mean coarse thumbnail (``P`` pixels,
            :func:`~driftmap.core.loop_closure.descriptors.thumbnails`).
        axes: ``(P, d)`` float32 principal axes of the descriptors (``(P, 0)``: centred thumbnails).
        desc: ``(G0, d)`` float32 descriptors of the search's first ``G0`` keyframes (a later search takes
            them instead of projecting those keyframes again; they are the same bit for bit).
        background: ``(4,)`` float64 median and sigma of d over random eligible pairs, ``d_t``, ``d_hit``.
    """

    mean: F32
    axes: F32
    desc: F32
    background: NDArray[np.float64]

    def prefix(self, frames: int) -> SearchBasis:
        """The basis with the descriptors of the first ``frames`` keyframes only."""
        return SearchBasis(self.mean, self.axes, self.desc[:frames], self.background)

    def to_arrays(self) -> dict[str, NDArray]:
        """Flat arrays for ``np.savez``."""
        return {f.name: np.asarray(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_arrays(cls, arrays: Mapping[str, NDArray]) -> SearchBasis:
        """Inverse of :meth:`to_arrays`."""
        return cls(
            mean=np.asarray(arrays["mean"], dtype=np.float32),
            axes=np.asarray(arrays["axes"], dtype=np.float32),
            desc=np.asarray(arrays["desc"], dtype=np.float32),
            background=np.asarray(arrays["background"], dtype=np.float64),
        )


def resumable_blocks(
    search: LoopSearch, p: LoopParams, blocks: Sequence[QueryScores], kept: int
) -> list[QueryScores]:
    """Of an earlier search's ``blocks``, the queries this ``search`` (planned with its basis) would score the
    same.

    Args:
        search: the new search, whose first ``kept`` keyframes are the earlier search's first ``kept``.
        p: the parameters of both.
        blocks: the earlier search's query blocks, in any order.
        kept: keyframes of the chains both searches share.

    Returns:
        The blocks from query 0 on, in order and without gaps, up to the last grid point of ``search`` (or its
        end) no later than ``kept``, the last one cut there (:meth:`QueryScores.head`); scoring may resume at
        the last one's end.
    """
    grid = [g for g in query_blocks(search.limit, p.coarse_block) if g <= kept]
    stop = search.n if kept >= search.n else (grid[-1] if grid else 0)
    out: list[QueryScores] = []
    for b in sorted(blocks, key=lambda b: b.q0):
        if b.q0 != (out[-1].q1 if out else 0) or b.q0 >= stop:
            break
        out.append(b.head(stop))
    return out
