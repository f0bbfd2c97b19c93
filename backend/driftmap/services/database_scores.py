"""SESAME database pair scores kept between map builds: a build scores only the pairs it has not seen.

Algorithm 1 (:mod:`driftmap.core.sesame.salient_database`) compares frames of one node that lie within
``A_th`` of each other; a pair's score depends on the two frames' thumbnails and the query's salient mask, not
on the poses. A :class:`~driftmap.store.models.MapDatabaseScores` row keeps the pairs a site's latest build
compared, by drive (its chain key, :func:`driftmap.services.loop_searches.chain_keys`, which fixes its frames,
thumbnails and masks) and frame row. The next build hands the pairs of the drives it still has to the
database (:func:`load_scores`): where the map moved a little, most nodes hold the same frames and their
comparisons are looked up; only pairs with new drives' frames, or newly close, are scored. A full build
(``full``) scores every pair. After a build :func:`keep_scores` records the pairs it used.

A kept blob that cannot be read is passed over (logged): the scores are only a shortcut, and the build scores
the pairs again.
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.core.mapping.pipeline import MappingParams
from driftmap.core.sesame.salient_database import PairScores
from driftmap.errors import BadInputError
from driftmap.services.loop_searches import json_digest
from driftmap.store.blobs import BlobBatch, BlobStore
from driftmap.store.models import MapDatabaseScores
from driftmap.store.npz import arrays_bytes, bytes_arrays

log = logging.getLogger(__name__)

SCORES_VERSION = 1
"""Version of the pair scores' algorithm and blob: bump it when either changes, and the next build scores
every pair again."""

_ARRAYS = ("query_drive", "query_row", "ref_drive", "ref_row", "d")


def scores_key(params: MappingParams) -> str:
    """SHA-256 (hex) of what a pair's score depends on besides its frames: the SESAME and SAD parameters,
    the thumbnails' and the code's version."""
    return json_digest(
        {
            "version": SCORES_VERSION,
            "sesame": dataclasses.asdict(params.database.sesame),
            "sad": dataclasses.asdict(params.loops.sad),
            "images": dataclasses.asdict(params.images),
        }
    )


def load_scores(
    session: Session,
    blobs: BlobStore,
    site_id: int,
    drives: Sequence[str],
    counts: Sequence[int],
    params: MappingParams,
    full: bool = False,
) -> PairScores:
    """The site's kept pair scores among this build's drives, by this build's flat frame index.

    Args:
        session: for the kept scores.
        blobs: where their blob is.
        site_id: the site built.
        drives: per drive of the build in order, its chain key.
        counts: per drive, its number of frames.
        params: the build's parameters.
        full: take none.

    Returns:
        The known pairs (none when ``full``, none kept, kept for other parameters or unreadable).
    """
    row = session.scalar(select(MapDatabaseScores).where(MapDatabaseScores.site_id == site_id))
    if full or row is None or row.scores_key != scores_key(params) or not blobs.exists(row.scores_sha256):
        return PairScores()
    try:
        arrays = bytes_arrays(blobs.get(row.scores_sha256), f"blob {row.scores_sha256}")
        return _pairs_now(arrays, row.drives, drives, counts)
    except (BadInputError, KeyError, IndexError, ValueError) as exc:
        log.warning("kept database pair scores of site %d passed over: %s", site_id, exc)
        return PairScores()


def _pairs_now(
    arrays: dict[str, NDArray[Any]], kept: Sequence[str], drives: Sequence[str], counts: Sequence[int]
) -> PairScores:
    """The kept pairs (drive positions in ``kept``, rows) among ``drives``, by flat frame index."""
    qd, qr, rd, rr, d = (np.asarray(arrays[name]) for name in _ARRAYS)
    where = {key: k for k, key in enumerate(drives)}
    now = np.array([where.get(key, -1) for key in kept] + [-1], dtype=np.int64)  # -1: not in this build
    size = np.r_[np.asarray(counts, dtype=np.int64), 0]
    ptr = np.r_[0, np.cumsum(counts)].astype(np.int64)
    qd, rd = now[np.clip(qd, -1, len(kept))], now[np.clip(rd, -1, len(kept))]
    ok = (qd >= 0) & (rd >= 0) & (qr >= 0) & (rr >= 0) & (qr < size[qd]) & (rr < size[rd])
    return PairScores(ptr[qd[ok]] + qr[ok], ptr[rd[ok]] + rr[ok], d[ok])


def keep_scores(
    session: Session,
    batch: BlobBatch,
    site_id: int,
    drives: Sequence[str],
    counts: Sequence[int],
    scores: PairScores,
    params: MappingParams,
) -> set[str]:
    """Record the pairs a build used as the site's kept scores, in the caller's transaction.

    Args:
        session: the build's transaction.
        batch: receives the scores' blob.
        site_id: the site built.
        drives: per drive of the build in order, its chain key.
        counts: per drive, its number of frames.
        scores: the build's pair scores (``MapBuild.database_scores``).
        params: the build's parameters.

    Returns:
        The blob of the earlier kept scores when this build replaced it: a candidate for
        :func:`driftmap.services.map_pieces.drop_stale` once committed.
    """
    q, r, d = scores.arrays()
    ptr = np.r_[0, np.cumsum(counts)].astype(np.int64)
    qd, rd = np.searchsorted(ptr, q, side="right") - 1, np.searchsorted(ptr, r, side="right") - 1
    sha = batch.put(
        arrays_bytes(
            {
                "query_drive": qd.astype(np.int32),
                "query_row": (q - ptr[qd]).astype(np.int32),
                "ref_drive": rd.astype(np.int32),
                "ref_row": (r - ptr[rd]).astype(np.int32),
                "d": d,
            }
        )
    )
    row = session.scalar(select(MapDatabaseScores).where(MapDatabaseScores.site_id == site_id))
    earlier: set[str] = set()
    if row is None:
        row = MapDatabaseScores(site_id=site_id)
        session.add(row)
    else:
        earlier = {row.scores_sha256}
    row.scores_key, row.drives, row.scores_sha256 = scores_key(params), list(drives), sha
    session.flush()
    return earlier - {sha}


def held_blobs(session: Session, shas: Iterable[str]) -> set[str]:
    """Those of ``shas`` kept scores hold."""
    wanted = sorted(set(shas))
    held: set[str] = set()
    for start in range(0, len(wanted), 500):
        chunk = wanted[start : start + 500]
        query = select(MapDatabaseScores.scores_sha256).where(MapDatabaseScores.scores_sha256.in_(chunk))
        held |= set(session.scalars(query))
    return held


def site_blobs(session: Session, site_id: int) -> set[str]:
    """The blob of the site's kept scores, if any."""
    query = select(MapDatabaseScores.scores_sha256).where(MapDatabaseScores.site_id == site_id)
    return set(session.scalars(query))
