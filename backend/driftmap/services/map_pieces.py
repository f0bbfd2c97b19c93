"""Stage-1 pieces kept between map builds: what lets a build skip the odometry of drives that did not change.

A build's stage 1 (:func:`driftmap.core.mapping.pipeline.prepare_segment`: visual odometry, thumbnails, frame
statistics of one drive segment) is most of its time and depends on little: the drive's frames and camera,
the segment's span, the parameters of the odometry, the thumbnails and the database, and the code. A
:class:`~driftmap.store.models.MapPiece` row keeps each segment's piece blob under a key hashing exactly
those (:func:`segment_keys`); the next build of the site loads the pieces whose key it finds
(:func:`kept_pieces`) and prepares only the rest. The one part of a piece that depends on the other drives
of a build, the quality classifier's frame sample, is retaken on loading
(:func:`driftmap.core.mapping.pipeline.restride_segment`), so an incremental build gives the pieces a
full one gives. After a build :func:`keep_pieces` records its pieces and drops its drives' pieces of other
keys (a drive re-imported, other parameters), whose blobs :func:`stale_blobs` then names for deletion.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Sequence
from typing import Any

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from driftmap.core.mapping.pipeline import MappingDrive, MappingParams, build_segments
from driftmap.services import database_scores, loop_searches
from driftmap.store.blobs import BlobStore
from driftmap.store.job_models import Job
from driftmap.store.models import Drive, MapPiece
from driftmap.store.storage import Storage

PIECE_VERSION = 1
"""Version of stage 1's algorithm and of the piece format: bump it when the odometry, the thumbnails or the
frame statistics change, and every kept piece is recomputed by the next build."""


def drive_content(drive: Drive, blob_sha256: Sequence[str], t_s: Sequence[float]) -> str:
    """SHA-256 (hex) of what a drive's stage 1 reads: its camera block, its frames' blobs and times (in frame
    order)."""
    return loop_searches.json_digest({"camera": drive.camera, "frames": list(blob_sha256), "t_s": list(t_s)})


def stage1_params(params: MappingParams) -> dict[str, Any]:
    """The parameters a piece depends on (odometry, thumbnails, database), as plain JSON."""
    return {
        "odometry": dataclasses.asdict(params.odometry),
        "images": dataclasses.asdict(params.images),
        "database": dataclasses.asdict(params.database),
    }


def segment_keys(
    drive_ids: Sequence[int], contents: Sequence[str], drives: Sequence[MappingDrive], params: MappingParams
) -> list[str]:
    """The piece key of every segment of a build, in :func:`build_segments` order.

    Args:
        drive_ids: per drive, its ``drives.id``.
        contents: per drive, :func:`drive_content`.
        drives: the drives as loaded for the pipeline.
        params: the build's parameters.
    """
    stage1 = stage1_params(params)
    return [
        loop_searches.json_digest(
            {
                "version": PIECE_VERSION,
                "drive_id": drive_ids[k],
                "content": contents[k],
                "span": list(span),
                "params": stage1,
            }
        )
        for k, span in build_segments(drives, params)
    ]


def kept_pieces(session: Session, blobs: BlobStore, keys: Iterable[str]) -> dict[str, str]:
    """Of ``keys``, those with a kept piece whose blob exists: key -> blob SHA-256."""
    wanted = sorted(set(keys))
    found: dict[str, str] = {}
    for start in range(0, len(wanted), 500):
        rows = session.execute(
            select(MapPiece.piece_key, MapPiece.blob_sha256).where(
                MapPiece.piece_key.in_(wanted[start : start + 500])
            )
        )
        found.update({key: sha for key, sha in rows if blobs.exists(sha)})
    return found


def keep_pieces(
    session: Session,
    drive_ids: Sequence[int],
    segments: Sequence[tuple[int, tuple[int, int], str, str]],
) -> set[str]:
    """Record a build's pieces and drop its drives' pieces of other keys, in the caller's transaction.

    Args:
        drive_ids: the build's drives (``drives.id``).
        segments: every segment of the build: (its drive's ``drives.id``, ``(first, stop)``, piece key, blob
            SHA-256).

    Returns:
        The blobs of the pieces dropped or replaced: candidates for :func:`stale_blobs` once committed.
    """
    rows = {p.piece_key: p for p in session.scalars(select(MapPiece).where(MapPiece.drive_id.in_(drive_ids)))}
    wanted = {key for _d, _s, key, _sha in segments}
    dropped = {p.blob_sha256 for key, p in rows.items() if key not in wanted}
    session.execute(
        delete(MapPiece).where(MapPiece.drive_id.in_(drive_ids), MapPiece.piece_key.not_in(wanted))
    )
    for drive_id, (first, stop), key, sha in segments:
        row = rows.get(key)
        if row is None:
            session.add(
                MapPiece(
                    drive_id=drive_id, piece_key=key, frame_first=first, frame_stop=stop, blob_sha256=sha
                )
            )
        elif row.blob_sha256 != sha:  # prepared again (a full build): the new blob replaces the old
            dropped.add(row.blob_sha256)
            row.blob_sha256 = sha
    session.flush()
    return dropped


def drive_piece_blobs(session: Session, drive_ids: Iterable[int]) -> set[str]:
    """The blobs of the kept pieces of the drives ``drive_ids``."""
    ids = list(drive_ids)
    return set(session.scalars(select(MapPiece.blob_sha256).where(MapPiece.drive_id.in_(ids))))


def stale_blobs(session: Session, shas: Iterable[str]) -> set[str]:
    """Those of ``shas`` no kept piece, loop-closure search or database pair scores hold and no unfinished job
    names (keys ending in ``_sha256``)."""
    wanted = set(shas)
    if not wanted:
        return set()
    held = set(session.scalars(select(MapPiece.blob_sha256).where(MapPiece.blob_sha256.in_(sorted(wanted)))))
    held |= loop_searches.held_blobs(session, wanted) | database_scores.held_blobs(session, wanted)
    unfinished = session.execute(select(Job.args, Job.result).where(Job.status.in_(("queued", "running"))))
    named = {
        str(v)
        for args, result in unfinished
        for values in (args or {}, result or {})
        for k, v in values.items()
        if k.endswith("_sha256")
    }
    return wanted - held - named


def drop_stale(storage: Storage, shas: Iterable[str]) -> int:
    """After the build that dropped them committed: delete the blobs of ``shas`` that are :func:`stale_blobs`."""
    with storage.db.session() as session:
        gone = stale_blobs(session, shas)
    for sha in gone:
        storage.blobs.delete(sha)
    return len(gone)
