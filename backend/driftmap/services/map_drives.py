"""A site's mapping drives for the pipeline: load one, run stage 1 on its segments, carry the results.

A map build's stage 1 (visual odometry, thumbnails, frame statistics, :func:`driftmap.core.mapping.pipeline.prepare_segment`)
is the bulk of its time and independent per drive segment. A ``map.drive`` job runs one segment of a stored
drive (:func:`load_mapping_drive` streams just its frames); :func:`prepare_site_drives` runs those an earlier
build did not keep (:mod:`driftmap.services.map_pieces`) in this process or in worker processes of this
machine (what ``driftmap map build`` does: the odometry is Python-bound, so threads share one core);
:func:`piece_bytes` and :func:`piece_from_bytes` turn a segment's result into bytes and back for the blob
store.
"""

from __future__ import annotations

import multiprocessing
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray
from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.core.mapping.drive import PreparedDrive, PreparedSegment
from driftmap.core.mapping.pipeline import (
    MappingDrive,
    MappingParams,
    build_segments,
    flat_offsets,
    join_segments,
    prepare_segment,
    restride_segment,
)
from driftmap.core.types import ProgressFn
from driftmap.errors import NotFoundError
from driftmap.processes import end_with_parent
from driftmap.services.drives import drive_meta, stored_frames
from driftmap.services.map_pieces import drive_content, segment_keys
from driftmap.store.blobs import BlobBatch, BlobStore
from driftmap.store.db import Database
from driftmap.store.models import Drive, Frame, Grounding, Site
from driftmap.store.npz import arrays_bytes, bytes_arrays


def _frame_range(blobs: BlobStore, shas: list[str]) -> Callable[[int, int], Iterator[NDArray[np.uint8]]]:
    def frames(begin: int, stop: int) -> Iterator[NDArray[np.uint8]]:
        return stored_frames(blobs, shas[begin:stop])

    return frames


@dataclass(frozen=True, eq=False)
class LoadedDrive:
    """One mapping drive loaded for the pipeline (frames streamed from the blob store) and its row ids."""

    drive: Drive
    input: MappingDrive
    frame_ids: NDArray[np.int64]
    """(N,) ``frames.id`` in frame order."""
    grounding_ids: list[int]
    """``groundings.id`` in the order of ``input.groundings``."""
    truth: NDArray[np.float64] | None
    """(N, 3) ground truth [x_m, y_m, yaw_rad] when every frame has it, else None."""
    content_sha256: str = ""
    """What its stage 1 reads, hashed (:func:`driftmap.services.map_pieces.drive_content`)."""


def load_mapping_drive(session: Session, blobs: BlobStore, drive: Drive) -> LoadedDrive:
    """``drive`` with its enabled groundings as the pipeline takes it, frames streamed from the blob store."""
    columns = (Frame.id, Frame.t_s, Frame.blob_sha256, Frame.true_x_m, Frame.true_y_m, Frame.true_yaw_rad)
    frames = session.execute(select(*columns).where(Frame.drive_id == drive.id).order_by(Frame.index)).all()
    position = {f.id: k for k, f in enumerate(frames)}
    marks = list(
        session.scalars(
            select(Grounding)
            .where(Grounding.drive_id == drive.id, Grounding.enabled.is_(True))
            .order_by(Grounding.id)
        )
    )
    has_truth = all(
        f.true_x_m is not None and f.true_y_m is not None and f.true_yaw_rad is not None for f in frames
    )
    truth = (
        np.array([[f.true_x_m, f.true_y_m, f.true_yaw_rad] for f in frames], dtype=np.float64)
        if has_truth
        else None
    )
    shas, times = [f.blob_sha256 for f in frames], [f.t_s for f in frames]
    frame_range = _frame_range(blobs, shas)
    mapping = MappingDrive(
        name=drive.name,
        camera=drive_meta(drive).camera,
        t_s=np.array(times, dtype=np.float64),
        frames=lambda: frame_range(0, len(frames)),
        groundings=[(position[g.frame_id], g.x_m, g.y_m) for g in marks],
        frame_range=frame_range,
    )
    ids = np.array([f.id for f in frames], dtype=np.int64)
    return LoadedDrive(drive, mapping, ids, [g.id for g in marks], truth, drive_content(drive, shas, times))


def mapping_drives(session: Session, site: Site) -> list[Drive]:
    """The mapping drives of ``site`` in build order (by id).

    Raises:
        NotFoundError: the site has none.
    """
    drives = list(
        session.scalars(
            select(Drive).where(Drive.site_id == site.id, Drive.kind == "mapping").order_by(Drive.id)
        )
    )
    if not drives:
        raise NotFoundError(f"site {site.name!r} has no mapping drive to build a map from")
    return drives


def piece_bytes(piece: PreparedSegment) -> bytes:
    """``piece`` as ``.npz`` bytes for the blob store."""
    return arrays_bytes(piece.to_arrays())


def piece_from_bytes(
    data: bytes, params: MappingParams, flat: tuple[int, int], drive: MappingDrive | None = None
) -> PreparedSegment:
    """The piece :func:`piece_bytes` wrote, for a build of ``params`` (``flat``: flat index of the segment's
    first frame, frames of the build). With its ``drive``, a piece another build prepared (other drives
    before it) gets the frame sample this build takes (:func:`restride_segment`)."""
    named = bytes_arrays(data, "a drive segment's prepared piece")
    piece = PreparedSegment.from_arrays(named, params.database, params.images, flat[0], flat[1])
    if drive is None:
        return piece
    sampled = None
    if "stats_first" in named and "stats_stride" in named:
        sampled = (int(named["stats_first"]), int(named["stats_stride"]))
    return restride_segment(piece, drive, params, sampled)


def _prepare_in_child(
    store: tuple[str, str], drive_id: int, params: MappingParams, flat: tuple[int, int], span: tuple[int, int]
) -> bytes:
    """Body of a worker process: open the (database URL, blob root) ``store``, prepare one segment of drive
    ``drive_id``."""
    db = Database(store[0])
    try:
        with db.session() as session:
            drive = session.get(Drive, drive_id)
            if drive is None:
                raise NotFoundError(f"drive {drive_id} does not exist (any more)")
            loaded = load_mapping_drive(session, BlobStore(Path(store[1])), drive)
        return piece_bytes(prepare_segment(loaded.input, params, flat, span))
    finally:
        db.dispose()


def single_threaded_worker() -> None:
    """Initializer of a pool whose processes fill the cores already: OpenCV on one thread each.

    OpenCV's default pool takes every core; with two odometry processes on two cores each spends ~45 %
    more CPU per frame on its second thread (28-29 vs 17-21 ms here) for no gain in wall time. A killed
    build takes its pool processes with it.
    """
    cv2.setNumThreads(1)
    end_with_parent()


def _segments_in_processes(
    store: tuple[str, Path],
    work: Sequence[tuple[int, tuple[int, int], tuple[int, int]]],
    params: MappingParams,
    workers: int,
    report: ProgressFn,
    meanwhile: Callable[[], None] = lambda: None,
) -> list[bytes]:
    """Stage 1 of the segments ``work`` ((drive id, flat, span) each) in up to ``workers`` fresh processes
    (spawned: no inherited connections); their pieces' bytes in order. ``meanwhile`` runs here once they
    are submitted."""
    context = multiprocessing.get_context("spawn")
    payload = (store[0], str(store[1]))
    done: list[bytes] = [b""] * len(work)
    processes = max(1, min(workers, len(work)))
    with ProcessPoolExecutor(processes, mp_context=context, initializer=single_threaded_worker) as pool:
        futures = {
            pool.submit(_prepare_in_child, payload, drive_id, params, flat, span): n
            for n, (drive_id, flat, span) in enumerate(work)
        }
        meanwhile()
        for count, future in enumerate(as_completed(futures), start=1):
            done[futures[future]] = future.result()
            report("odometry", count / len(work))
    return done


@dataclass(frozen=True, eq=False)
class StageOne:
    """Stage 1 of a build's drives, with the pieces it kept and reused."""

    pieces: list[PreparedDrive]
    """Per drive, its joined piece."""
    segments: list[tuple[int, tuple[int, int], str, str]]
    """Per segment: (drive id, ``(first, stop)``, piece key, blob SHA-256), for :func:`~driftmap.services.map_pieces.keep_pieces`."""
    reused: int
    """Segments whose kept piece was loaded."""


def prepare_site_drives(
    store: tuple[str, Path],
    batch: BlobBatch,
    drives: Sequence[tuple[int, str, MappingDrive]],
    params: MappingParams,
    kept: Callable[[list[str]], dict[str, str]],
    workers: int = 1,
    progress: ProgressFn | None = None,
) -> StageOne:
    """Stage 1 of stored drives: the kept pieces loaded, the other segments prepared (in this process, or in
    up to ``workers`` worker processes) and stored as blobs; joined per drive.

    Args:
        store: (database URL with its password, blob store root) holding the drives.
        batch: where the new pieces' blobs go (kept once the caller commits).
        drives: (drive id, :func:`~driftmap.services.map_pieces.drive_content`, the drive as loaded here), in
            build order.
        params: the build's parameters.
        kept: piece keys -> the kept pieces among them (key -> blob SHA-256); ``lambda _k: {}`` for a full build.
        workers: processes at most (1: this process).
        progress: called with ("odometry", fraction of the segments to prepare done).

    Returns:
        The pieces, bit-identical to preparing every segment in this process.
    """
    report = progress or (lambda _stage, _fraction: None)
    report("odometry", 0.0)
    inputs = [d for _i, _c, d in drives]
    flats = flat_offsets(inputs)
    segments = build_segments(inputs, params)
    keys = segment_keys([i for i, _c, _d in drives], [c for _i, c, _d in drives], inputs, params)
    found = kept(keys)
    todo = [n for n, key in enumerate(keys) if key not in found]
    work = [(drives[k][0], flats[k], span) for k, span in (segments[n] for n in todo)]
    blobs = BlobStore(Path(store[1]))
    of_drive = [[n for n, (j, _span) in enumerate(segments) if j == k] for k in range(len(inputs))]

    def join(k: int, fresh: dict[str, bytes]) -> PreparedDrive:
        """Drive ``k``'s piece: its segments' pieces (``fresh`` or kept) loaded and joined."""
        done = []
        for n in of_drive[k]:
            data = fresh[keys[n]] if keys[n] in fresh else blobs.get(found[keys[n]])
            first = flats[k][0] + segments[n][1][0]
            done.append(piece_from_bytes(data, params, (first, flats[k][1]), inputs[k]))
        return join_segments(inputs[k], done, params)

    joined: dict[int, PreparedDrive] = {}
    kept_drives = [k for k, ns in enumerate(of_drive) if all(keys[n] in found for n in ns)]

    def join_kept() -> None:
        joined.update({k: join(k, {}) for k in kept_drives})

    if workers > 1 and len(work) > 1:  # the drives with nothing to prepare joined while the workers run
        made = _segments_in_processes(store, work, params, workers, report, join_kept)
    else:
        made = []
        for count, n in enumerate(todo, start=1):
            k, span = segments[n]
            made.append(piece_bytes(prepare_segment(inputs[k], params, flats[k], span)))
            report("odometry", count / len(todo))
    fresh = {keys[n]: data for n, data in zip(todo, made, strict=True)}
    shas = dict(found) | {key: batch.put(data) for key, data in fresh.items()}
    pieces = [joined[k] if k in joined else join(k, fresh) for k in range(len(inputs))]
    rows = [(drives[k][0], span, key, shas[key]) for (k, span), key in zip(segments, keys, strict=True)]
    return StageOne(pieces, rows, len(segments) - len(todo))
