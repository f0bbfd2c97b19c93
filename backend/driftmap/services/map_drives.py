"""A site's mapping drives for the pipeline, one at a time: load one, run its stage 1, carry the result.

A map build's stage 1 (visual odometry, thumbnails, frame statistics of one drive,
:func:`driftmap.core.mapping.prepare_drive`) is the bulk of its time and independent per drive. This module
runs it on a stored drive in this process (:func:`prepare_stored_drive`, what a ``map.drive`` job does), in
worker processes of this machine (:func:`prepare_in_processes`, what ``driftmap map build`` does: the
odometry is Python-bound, so threads share one core), and turns its result into bytes and back
(:func:`piece_bytes`, :func:`piece_from_bytes`) for the blob store.
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

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.core.drive_prep import PreparedDrive
from driftmap.core.mapping import MappingDrive, MappingParams, prepare_drive
from driftmap.errors import BadInputError, NotFoundError
from driftmap.formats.frame_images import decode_gray
from driftmap.services.drives import drive_meta, frame_rows
from driftmap.store.blobs import BlobStore
from driftmap.store.db import Database
from driftmap.store.models import Drive, Grounding, Site

ProgressFn = Callable[[str, float], None]


def _frame_source(blobs: BlobStore, shas: list[str]) -> Callable[[], Iterator[NDArray[np.uint8]]]:
    def frames() -> Iterator[NDArray[np.uint8]]:
        for sha in shas:
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
    """``drive`` with its groundings as the pipeline takes it, frames streamed from the blob store."""
    frames = frame_rows(session, drive)
    position = {f.id: k for k, f in enumerate(frames)}
    marks = list(
        session.scalars(select(Grounding).where(Grounding.drive_id == drive.id).order_by(Grounding.id))
    )
    has_truth = all(
        f.true_x_m is not None and f.true_y_m is not None and f.true_yaw_rad is not None for f in frames
    )
    truth = (
        np.array([[f.true_x_m, f.true_y_m, f.true_yaw_rad] for f in frames], dtype=np.float64)
        if has_truth
        else None
    )
    mapping = MappingDrive(
        name=drive.name,
        camera=drive_meta(drive).camera,
        t_s=np.array([f.t_s for f in frames], dtype=np.float64),
        frames=_frame_source(blobs, [f.blob_sha256 for f in frames]),
        groundings=[(position[g.frame_id], g.x_m, g.y_m) for g in marks],
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


def prepare_stored_drive(
    session: Session,
    blobs: BlobStore,
    drive: Drive,
    params: MappingParams,
    flat: tuple[int, int],
    report: Callable[[float], None] | None = None,
) -> PreparedDrive:
    """Stage 1 of a stored mapping drive (see :func:`driftmap.core.mapping.prepare_drive` for ``flat``)."""
    loaded = load_mapping_drive(session, blobs, drive)
    return prepare_drive(loaded.input, params, flat, report)


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


def piece_bytes(piece: PreparedDrive) -> bytes:
    """``piece`` as ``.npz`` bytes for the blob store."""
    return arrays_bytes(piece.to_arrays())


def piece_from_bytes(data: bytes, params: MappingParams, flat: tuple[int, int]) -> PreparedDrive:
    """The piece :func:`piece_bytes` wrote, for a build of ``params`` (``flat`` as it was prepared with)."""
    named = bytes_arrays(data, "a drive's prepared piece")
    return PreparedDrive.from_arrays(named, params.database, params.images, flat[0], flat[1])


def _prepare_in_child(
    store: tuple[str, str], drive_id: int, params: MappingParams, flat: tuple[int, int]
) -> bytes:
    """Body of a worker process: open the (database URL, blob root) ``store``, prepare drive ``drive_id``."""
    db = Database(store[0])
    try:
        with db.session() as session:
            drive = session.get(Drive, drive_id)
            if drive is None:
                raise NotFoundError(f"drive {drive_id} does not exist (any more)")
            loaded = load_mapping_drive(session, BlobStore(Path(store[1])), drive)
        return piece_bytes(prepare_drive(loaded.input, params, flat))
    finally:
        db.dispose()


def prepare_in_processes(
    store: tuple[str, Path],
    drive_ids: Sequence[int],
    params: MappingParams,
    flats: Sequence[tuple[int, int]],
    workers: int,
    progress: ProgressFn | None = None,
) -> list[PreparedDrive]:
    """Stage 1 of stored drives in up to ``workers`` fresh processes (spawned: no inherited connections).

    Args:
        store: (database URL with its password, blob store root) holding the drives.
        drive_ids: the drives, in build order.
        params: the build's parameters.
        flats: per drive, (flat index of its first frame, frames of all drives).
        workers: processes at most (one per drive at most).
        progress: called with ("odometry", fraction of drives done).

    Returns:
        The pieces in the order of ``drive_ids``, bit-identical to preparing them in this process.
    """
    report = progress or (lambda _stage, _fraction: None)
    report("odometry", 0.0)
    context = multiprocessing.get_context("spawn")
    payload = (store[0], str(store[1]))
    with ProcessPoolExecutor(max(1, min(workers, len(drive_ids))), mp_context=context) as pool:
        futures = {
            pool.submit(_prepare_in_child, payload, drive_id, params, flat): k
            for k, (drive_id, flat) in enumerate(zip(drive_ids, flats, strict=True))
        }
        out: list[PreparedDrive | None] = [None] * len(drive_ids)
        for done, future in enumerate(as_completed(futures), start=1):
            k = futures[future]
            out[k] = piece_from_bytes(future.result(), params, flats[k])
            report("odometry", done / len(drive_ids))
    return [p for p in out if p is not None]
