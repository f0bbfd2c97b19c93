"""A site's mapping drives for the pipeline: load one, run stage 1 on its segments, carry the results.

A map build's stage 1 (visual odometry, thumbnails, frame statistics, :func:`driftmap.core.mapping.pipeline.prepare_segment`)
is the bulk of its time and independent per drive segment. A ``map.drive`` job runs one segment of a stored
drive (:func:`load_mapping_drive` streams just its frames); :func:`prepare_in_processes` runs them all in worker
processes of this machine (what ``driftmap map build`` does: the odometry is Python-bound, so threads share
one core); :func:`piece_bytes` and :func:`piece_from_bytes` turn a segment's result into bytes and back for
the blob store.
"""

from __future__ import annotations

import io
import multiprocessing
import zipfile
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

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
)
from driftmap.core.types import ProgressFn
from driftmap.errors import BadInputError, NotFoundError
from driftmap.formats.frame_images import decode_gray
from driftmap.services.drives import drive_meta, frame_rows
from driftmap.store.blobs import BlobStore
from driftmap.store.db import Database
from driftmap.store.models import Drive, Grounding, Site


def _frame_range(blobs: BlobStore, shas: list[str]) -> Callable[[int, int], Iterator[NDArray[np.uint8]]]:
    def frames(begin: int, stop: int) -> Iterator[NDArray[np.uint8]]:
        for sha in shas[begin:stop]:
            yield decode_gray(blobs.get(sha), f"blob {sha}")

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


def load_mapping_drive(session: Session, blobs: BlobStore, drive: Drive) -> LoadedDrive:
    """``drive`` with its enabled groundings as the pipeline takes it, frames streamed from the blob store."""
    frames = frame_rows(session, drive)
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
    frame_range = _frame_range(blobs, [f.blob_sha256 for f in frames])
    mapping = MappingDrive(
        name=drive.name,
        camera=drive_meta(drive).camera,
        t_s=np.array([f.t_s for f in frames], dtype=np.float64),
        frames=lambda: frame_range(0, len(frames)),
        groundings=[(position[g.frame_id], g.x_m, g.y_m) for g in marks],
        frame_range=frame_range,
    )
    ids = np.array([f.id for f in frames], dtype=np.int64)
    return LoadedDrive(drive, mapping, ids, [g.id for g in marks], truth)


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


def arrays_bytes(arrays: dict[str, NDArray[Any]]) -> bytes:
    """Named arrays as an uncompressed ``.npz`` (thumbnails are noise-like: compression gains little)."""
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    return buffer.getvalue()


def bytes_arrays(data: bytes, what: str) -> dict[str, NDArray[Any]]:
    """The arrays :func:`arrays_bytes` wrote.

    Raises:
        BadInputError: ``data`` (named ``what`` in the message) is no ``.npz``.
    """
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as arrays:
            return {k: arrays[k] for k in arrays.files}
    except (OSError, ValueError, zipfile.BadZipFile) as exc:
        raise BadInputError(f"{what} is not a readable .npz: {exc}") from exc


def piece_bytes(piece: PreparedSegment) -> bytes:
    """``piece`` as ``.npz`` bytes for the blob store."""
    return arrays_bytes(piece.to_arrays())


def piece_from_bytes(data: bytes, params: MappingParams, flat: tuple[int, int]) -> PreparedSegment:
    """The piece :func:`piece_bytes` wrote, for a build of ``params`` (``flat``: flat index of the segment's
    first frame, frames of the build)."""
    named = bytes_arrays(data, "a drive segment's prepared piece")
    return PreparedSegment.from_arrays(named, params.database, params.images, flat[0], flat[1])


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
    more CPU per frame on its second thread (28-29 vs 17-21 ms here) for no gain in wall time.
    """
    cv2.setNumThreads(1)


def prepare_in_processes(
    store: tuple[str, Path],
    drives: Sequence[tuple[int, MappingDrive]],
    params: MappingParams,
    workers: int,
    progress: ProgressFn | None = None,
) -> list[PreparedDrive]:
    """Stage 1 of stored drives, segment by segment in up to ``workers`` fresh processes (spawned: no
    inherited connections), joined per drive here.

    Args:
        store: (database URL with its password, blob store root) holding the drives.
        drives: (drive id, the drive as loaded here), in build order.
        params: the build's parameters.
        workers: processes at most.
        progress: called with ("odometry", fraction of segments done).

    Returns:
        The drives' pieces in order, bit-identical to preparing them in this process.
    """
    report = progress or (lambda _stage, _fraction: None)
    report("odometry", 0.0)
    inputs = [d for _i, d in drives]
    flats = flat_offsets(inputs)
    segments = build_segments(inputs, params)
    context = multiprocessing.get_context("spawn")
    payload = (store[0], str(store[1]))
    processes = max(1, min(workers, len(segments)))
    with ProcessPoolExecutor(processes, mp_context=context, initializer=single_threaded_worker) as pool:
        futures = {
            pool.submit(_prepare_in_child, payload, drives[k][0], params, flats[k], span): n
            for n, (k, span) in enumerate(segments)
        }
        done: list[PreparedSegment | None] = [None] * len(segments)
        for count, future in enumerate(as_completed(futures), start=1):
            n = futures[future]
            k, (first, _stop) = segments[n]
            done[n] = piece_from_bytes(future.result(), params, (flats[k][0] + first, flats[k][1]))
            report("odometry", count / len(segments))
    return [
        join_segments(d, [s for (j, _span), s in zip(segments, done, strict=True) if j == k and s], params)
        for k, d in enumerate(inputs)
    ]
