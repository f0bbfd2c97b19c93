"""Loop-closure searches kept between map builds: what lets a build score only the new drives' keyframes.

A build's loop-closure search (:mod:`driftmap.core.loop_closure.blocks`) compares every keyframe with the
earlier ones, chain after chain (a chain is one drive's keyframes, drives in recording order). A
:class:`~driftmap.store.models.MapLoopSearch` row keeps a site's latest search: the key of each chain (hashing
its drive's stage-1 pieces, :func:`chain_keys`), the search's basis and its query blocks' scores as blobs. The
next build whose first chains have those keys resumes it (:func:`plan_loops`): the basis' descriptors and
thresholds plan the search, the blocks within those chains are taken as they are, and only the queries after
them are scored. The closures are then decided over all queries as always.

The basis (descriptor axes, background thresholds) comes from the first ``basis_keyframes`` keyframes
(:class:`~driftmap.core.loop_closure.params.LoopParams`), or all of them on a site with fewer. A build resumes
the kept search only when a plan afresh would have the same basis: the chains it shares hold the keyframes the
kept basis came from, and it would take as many. The resumed search is then the search a full build (``full``,
always planned afresh) makes. A site with fewer keyframes is searched afresh by every build that adds or
changes a drive, and resumed by one that changed none (a moved grounding). After a build :func:`keep_search`
records its search and returns the blobs of the earlier one it no longer holds (for
:func:`driftmap.services.map_pieces.drop_stale`).
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.core.loop_closure.blocks import (
    LoopSearch,
    QueryScores,
    plan_search,
    score_queries,
    split_queries,
)
from driftmap.core.loop_closure.resume import SearchBasis, resumable_blocks
from driftmap.core.loop_closure.search import LoopResult, decide_loops
from driftmap.core.mapping.pipeline import MappingDrive, MappingParams, build_segments
from driftmap.core.types import ProgressFn
from driftmap.store.blobs import BlobBatch, BlobStore
from driftmap.store.models import MapLoopSearch
from driftmap.store.npz import arrays_bytes, bytes_arrays

SEARCH_VERSION = 2
"""Version of the search's algorithm and of its kept blobs: bump it when either changes, and the next build
searches afresh."""

QUERIES_PER_BLOCK = 1024
"""Query keyframes per scored block (whole blocks of the coarse ranking; a ``map.loops`` subtask each)."""

ScoredBlock = tuple[QueryScores, str]
"""A block's scores and the blob holding them."""


def json_digest(document: Any) -> str:
    """SHA-256 (hex) of a JSON document, keys sorted: the keys of what map builds keep."""
    text = json.dumps(document, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(text.encode()).hexdigest()


def search_key(params: MappingParams) -> str:
    """SHA-256 (hex) of what a search depends on besides its chains: its parameters and the code's version."""
    return json_digest(
        {
            "version": SEARCH_VERSION,
            "loops": dataclasses.asdict(params.loops),
            "keyframe_spacing_m": params.keyframe_spacing_m,
        }
    )


def chain_keys(piece_keys: Sequence[str], drives: Sequence[MappingDrive], params: MappingParams) -> list[str]:
    """Per drive, the key of its chain of keyframes: a hash of its segments' piece keys
    (:func:`driftmap.services.map_pieces.segment_keys`, in :func:`build_segments` order), which fix its
    keyframes, their thumbnails and times."""
    per_drive: list[list[str]] = [[] for _d in drives]
    for key, (k, _span) in zip(piece_keys, build_segments(drives, params), strict=True):
        per_drive[k].append(key)
    return [json_digest(keys) for keys in per_drive]


@dataclass(frozen=True, eq=False)
class LoopPlan:
    """A build's search, what it resumes of the kept one, and what remains to score.

    Attributes:
        search: the plan of the whole search.
        basis_sha256: the blob of its basis (new in the batch).
        kept: the kept search's blocks it takes as they are, in query order.
        ranges: the query ranges ``(q0, q1)`` still to score, in order.
    """

    search: LoopSearch
    basis_sha256: str
    kept: list[ScoredBlock]
    ranges: list[tuple[int, int]]

    @property
    def queries_kept(self) -> int:
        """Queries whose scores are taken from the kept search."""
        return self.kept[-1][0].q1 if self.kept else 0


def plan_loops(
    session: Session,
    blobs: BlobStore,
    batch: BlobBatch,
    site_id: int,
    chains: tuple[Sequence[str], Sequence[NDArray[np.float32]], Sequence[NDArray[np.float64]]],
    params: MappingParams,
    full: bool = False,
) -> LoopPlan | None:
    """Plan a build's loop-closure search, resuming the site's kept one where its chains allow.

    Args:
        session: for the kept search.
        blobs: where its blobs are.
        batch: receives the basis blob of the search.
        site_id: the site built.
        chains: per drive in recording order, its chain key (:func:`chain_keys`), ``(K_d, h, w)`` keyframe
            thumbnails and ``(K_d,)`` times, s (:func:`driftmap.core.mapping.prepare.loop_inputs`).
        params: the build's parameters.
        full: plan afresh whatever was kept.

    Returns:
        The plan, or None when no keyframe has an eligible earlier one.
    """
    keys, thumbs, times = chains
    p = params.loops
    earlier = None if full else _kept(session, blobs, site_id, params, keys, [len(t) for t in thumbs])
    search = plan_search(thumbs, p, times, basis=earlier[0] if earlier else None)
    if search is None:
        return None
    kept: list[ScoredBlock] = []
    if earlier is not None:
        _basis, blocks, kept_frames = earlier
        sha_of = {b.q0: sha for b, sha in blocks}
        kept = [(b, sha_of[b.q0]) for b in resumable_blocks(search, p, [b for b, _ in blocks], kept_frames)]
    start = kept[-1][0].q1 if kept else 0
    basis_sha = batch.put(arrays_bytes(search.basis().to_arrays()))
    return LoopPlan(search, basis_sha, kept, split_queries(search, p, QUERIES_PER_BLOCK, start))


def score_here(
    plan: LoopPlan, params: MappingParams, batch: BlobBatch, progress: ProgressFn | None = None
) -> list[ScoredBlock]:
    """Score ``plan.ranges`` in this process, each block's scores put in ``batch``."""
    scored: list[ScoredBlock] = []
    for k, (q0, q1) in enumerate(plan.ranges):
        if progress is not None:
            progress("loop closure", k / len(plan.ranges))
        block = score_queries(plan.search, params.loops, q0, q1)
        scored.append((block, batch.put(arrays_bytes(block.to_arrays()))))
    return scored


def decide(plan: LoopPlan, params: MappingParams, scored: Sequence[ScoredBlock]) -> LoopResult:
    """The closures of a plan whose remaining ranges are ``scored``."""
    return decide_loops(plan.search, [b for b, _sha in [*plan.kept, *scored]], params.loops)


def _kept(
    session: Session,
    blobs: BlobStore,
    site_id: int,
    params: MappingParams,
    chains: Sequence[str],
    sizes: Sequence[int],
) -> tuple[SearchBasis, list[ScoredBlock], int] | None:
    """The kept search of the site, if it can be resumed: its basis (descriptors of the shared chains'
    keyframes), blocks within the shared chains, and those chains' keyframes."""
    row = session.scalar(select(MapLoopSearch).where(MapLoopSearch.site_id == site_id))
    if row is None or row.search_key != search_key(params) or not blobs.exists(row.basis_sha256):
        return None
    shared = 0
    while shared < min(len(row.chains), len(chains)) and row.chains[shared] == chains[shared]:
        shared += 1
    kept_frames = int(sum(sizes[:shared]))
    if shared == 0:
        return None
    basis = SearchBasis.from_arrays(bytes_arrays(blobs.get(row.basis_sha256), f"blob {row.basis_sha256}"))
    # Its basis came from its first min(K, n) keyframes: the one a plan afresh has only if that is the same
    # number now and those keyframes are shared.
    first = min(params.loops.basis_keyframes, basis.desc.shape[0])
    if basis.desc.shape[0] < kept_frames or kept_frames < first:
        return None
    if first != min(params.loops.basis_keyframes, int(sum(sizes))):
        return None
    blocks: list[ScoredBlock] = []
    for q0, q1, sha in sorted(row.blocks):
        if q0 >= kept_frames or not blobs.exists(sha):
            break
        scores = QueryScores.from_arrays(bytes_arrays(blobs.get(sha), f"blob {sha}"))
        blocks.append((scores.head(int(q1)), str(sha)))  # a block an earlier build cut short stays cut
    return basis.prefix(kept_frames), blocks, kept_frames


def keep_search(
    session: Session,
    site_id: int,
    params: MappingParams,
    chains: Sequence[str],
    plan: LoopPlan,
    scored: Sequence[ScoredBlock],
) -> set[str]:
    """Record a build's search as the site's kept one, in the caller's transaction.

    Args:
        session: the build's transaction.
        site_id: the site built.
        params: the build's parameters.
        chains: the build's chain keys (:func:`chain_keys`), in search order.
        plan: the build's plan.
        scored: the blocks of ``plan.ranges``, scored, with their blobs.

    Returns:
        The blobs of the earlier kept search this one no longer holds: candidates for
        :func:`driftmap.services.map_pieces.drop_stale` once committed.
    """
    row = session.scalar(select(MapLoopSearch).where(MapLoopSearch.site_id == site_id))
    blocks = [[b.q0, b.q1, sha] for b, sha in [*plan.kept, *scored]]
    held = {plan.basis_sha256, *(sha for _q0, _q1, sha in blocks)}
    if row is None:
        row = MapLoopSearch(site_id=site_id)
        session.add(row)
        earlier: set[str] = set()
    else:
        earlier = {row.basis_sha256, *(str(sha) for _q0, _q1, sha in row.blocks)}
    row.search_key, row.chains, row.basis_sha256, row.blocks = (
        search_key(params),
        list(chains),
        plan.basis_sha256,
        blocks,
    )
    session.flush()
    return earlier - held


def held_blobs(session: Session, shas: Iterable[str]) -> set[str]:
    """Those of ``shas`` a kept search holds."""
    wanted = set(shas)
    held: set[str] = set()
    for basis, blocks in session.execute(select(MapLoopSearch.basis_sha256, MapLoopSearch.blocks)):
        held |= {basis, *(str(sha) for _q0, _q1, sha in blocks)} & wanted
    return held


def site_blobs(session: Session, site_id: int) -> set[str]:
    """The blobs the site's kept search holds."""
    row = session.scalar(select(MapLoopSearch).where(MapLoopSearch.site_id == site_id))
    return set() if row is None else {row.basis_sha256, *(str(sha) for _q0, _q1, sha in row.blocks)}
