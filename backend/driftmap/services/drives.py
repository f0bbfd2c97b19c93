"""Drives: import from drive folders and videos, export, list.

An import validates the whole drive before it is visible: rows are flushed inside the caller's
transaction and every new blob is tracked by the caller's :class:`BlobBatch`, so a failure at any
frame leaves neither rows nor orphan blobs once the caller's ``with`` blocks unwind.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import func, insert, select
from sqlalchemy.orm import Session

from driftmap.core.odometry.camera import CameraModel
from driftmap.core.types import ProgressFn
from driftmap.errors import BadInputError, ConflictError, NotFoundError
from driftmap.formats.drive_folder import (
    DriveFolder,
    iter_frame_images,
    read_drive_folder,
    write_drive_folder,
)
from driftmap.formats.drive_json import camera_to_json, parse_camera_block
from driftmap.formats.frame_images import decode_gray
from driftmap.formats.records import DriveKind, DriveMeta, FrameRow, GroundingRow
from driftmap.formats.video import read_calibration_json, read_video_drive
from driftmap.store.blobs import BlobBatch, BlobStore
from driftmap.store.models import Drive, Frame, Grounding, Site

VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv")


@dataclass(frozen=True)
class DriveSummary:
    """One line of a drive listing."""

    id: int
    name: str
    kind: str
    fps: float
    frame_count: int
    duration_s: float
    grounding_count: int
    has_truth: bool


def drive_folders_in(root: Path) -> list[Path]:
    """The drive folders (those holding a drive.json) directly inside ``root``, sorted by name."""
    if not root.is_dir():
        raise BadInputError("not a folder", file=root)
    folders = sorted(p for p in root.iterdir() if (p / "drive.json").is_file())
    if not folders:
        raise BadInputError("holds no drive folder (a folder with drive.json)", file=root)
    return folders


def with_camera(folder: DriveFolder, camera: CameraModel) -> DriveFolder:
    """The folder with ``camera`` instead of its ``drive.json`` block.

    Raises:
        BadInputError: the camera's frame size is not the folder's (naming both).
    """
    own = folder.meta.camera
    if (camera.width_px, camera.height_px) != (own.width_px, own.height_px):
        raise BadInputError(
            f"the camera is {camera.width_px}x{camera.height_px}, the drive's frames "
            f"{own.width_px}x{own.height_px}",
            file=folder.path,
            field="camera",
        )
    return dataclasses.replace(folder, meta=dataclasses.replace(folder.meta, camera=camera))


def get_drive(session: Session, site: Site, name_or_id: str | int) -> Drive:
    """The drive of ``site`` with that name (or numeric id)."""
    drive = session.scalar(select(Drive).where(Drive.site_id == site.id, Drive.name == str(name_or_id)))
    if drive is None and str(name_or_id).isdigit():
        drive = session.scalar(select(Drive).where(Drive.site_id == site.id, Drive.id == int(name_or_id)))
    if drive is None:
        raise NotFoundError(f"site {site.name!r} has no drive named {name_or_id!r}")
    return drive


def import_drive(
    session: Session,
    batch: BlobBatch,
    site: Site,
    path: Path,
    *,
    progress: ProgressFn | None = None,
    calibration: str | None = None,
    camera: CameraModel | None = None,
    name: str | None = None,
    kind: str = "mapping",
) -> Drive:
    """Import a drive folder, or a video file with its calibration JSON, into ``site``.

    Args:
        session: open session; the caller commits.
        batch: tracks new blobs so that the caller can remove them if the import fails.
        site: the site receiving the drive.
        path: a drive folder (``docs/formats.md``) or an mp4/avi/mov/mkv video file.
        progress: called with ``("import", fraction of frames done)``.
        calibration: a JSON file with the camera block: a video's calibration (it or ``camera`` is
            required), or for a folder one that replaces its ``drive.json`` camera block.
        camera: the camera the drive was recorded with (a camera profile's block), instead of ``calibration``.
        name: for a video, the drive name (default: the file stem).
        kind: for a video, ``mapping`` or ``localisation``.

    Raises:
        BadInputError: a bad folder or video, both ``calibration`` and ``camera``, or a camera whose frame
            size is not the folder's.
    """
    if calibration is not None and camera is not None:
        raise BadInputError("give a calibration file or a camera profile, not both", field="calibration")
    if calibration is not None and path.is_dir():
        camera, _ = read_calibration_json(Path(calibration))
    if path.is_dir():
        folder = read_drive_folder(path)
        if camera is not None:
            folder = with_camera(folder, camera)
        _ensure_new_name(session, site, folder.meta.name)
        pairs: Iterable[tuple[FrameRow, bytes, str]] = (
            (row, data, file.suffix.lower())
            for (row, data), file in zip(iter_frame_images(folder), folder.frame_files, strict=True)
        )
        return _store_drive(
            session, batch, site, folder.meta, folder.frames, pairs, folder.groundings, str(path), progress
        )
    if not path.exists():
        raise BadInputError("no such file or folder", file=path)
    if path.suffix.lower() not in VIDEO_SUFFIXES:
        raise BadInputError(f"neither a drive folder nor a video ({', '.join(VIDEO_SUFFIXES)})", file=path)
    if calibration is None and camera is None:
        raise BadInputError(
            "a video import needs --calibration (the camera JSON) or --profile",
            file=path,
            field="calibration",
        )
    source = camera if camera is not None else Path(str(calibration))
    meta, rows, images = read_video_drive(path, source, name=name or path.stem, kind=kind)
    _ensure_new_name(session, site, meta.name)
    video_pairs = ((row, data, ".png") for row, data in zip(rows, images, strict=True))
    return _store_drive(session, batch, site, meta, rows, video_pairs, [], str(path), progress)


def _ensure_new_name(session: Session, site: Site, name: str) -> None:
    if session.scalar(select(Drive.id).where(Drive.site_id == site.id, Drive.name == name)) is not None:
        raise ConflictError(f"site {site.name!r} already has a drive named {name!r}")


def _store_drive(
    session: Session,
    batch: BlobBatch,
    site: Site,
    meta: DriveMeta,
    rows: list[FrameRow],
    images: Iterable[tuple[FrameRow, bytes, str]],
    groundings: list[GroundingRow],
    source: str,
    progress: ProgressFn | None,
) -> Drive:
    drive = Drive(
        site_id=site.id,
        name=meta.name,
        kind=meta.kind,
        fps=meta.fps,
        camera=camera_to_json(meta.camera),
        frame_count=len(rows),
        source=source,
    )
    frame_rows: list[dict[str, object]] = []
    step = max(1, len(rows) // 100)
    for done, (row, data, ext) in enumerate(images, start=1):
        frame_rows.append(
            {
                "index": row.frame,
                "t_s": row.t_s,
                "blob_sha256": batch.put(data),
                "image_ext": ext,
                "true_x_m": row.x_m,
                "true_y_m": row.y_m,
                "true_yaw_rad": row.yaw_rad,
            }
        )
        if progress is not None and done % step == 0:
            progress("import", done / len(rows))
    # Rows are written only now, so the database is locked for writing only briefly (SQLite) and
    # progress callbacks above may write to the database from other connections.
    if progress is not None:
        progress("import", 1.0)
    session.add(drive)
    session.flush()
    if frame_rows:
        session.execute(insert(Frame), [{**r, "drive_id": drive.id} for r in frame_rows])
    if groundings:
        ids = dict(session.execute(select(Frame.index, Frame.id).where(Frame.drive_id == drive.id)).all())
        session.execute(
            insert(Grounding),
            [
                {
                    "drive_id": drive.id,
                    "frame_id": ids[g.frame],
                    "x_m": g.x_m,
                    "y_m": g.y_m,
                    "station": g.station,
                    "enabled": g.enabled,
                    "created_by": "import",
                }
                for g in groundings
            ],
        )
    session.flush()
    return drive


def drive_meta(drive: Drive) -> DriveMeta:
    """The stored drive's ``drive.json`` contents."""
    camera = parse_camera_block(drive.camera, "", f"drive {drive.name!r}")
    kind: DriveKind = "mapping" if drive.kind == "mapping" else "localisation"
    return DriveMeta(name=drive.name, kind=kind, fps=drive.fps, camera=camera)


def frame_rows(session: Session, drive: Drive) -> list[Frame]:
    """The frames of ``drive`` in frame order."""
    return list(session.scalars(select(Frame).where(Frame.drive_id == drive.id).order_by(Frame.index)))


def stored_frames(blobs: BlobStore, shas: Iterable[str]) -> Iterator[NDArray[np.uint8]]:
    """The gray ``(H, W)`` uint8 frames stored under ``shas`` (``frames.blob_sha256``), decoded one at a time."""
    for sha in shas:
        yield decode_gray(blobs.get(sha), f"blob {sha}")


def grounding_rows(session: Session, drive: Drive) -> list[GroundingRow]:
    """The groundings of ``drive`` as formats.md rows, in frame order."""
    query = (
        select(Frame.index, Grounding.x_m, Grounding.y_m, Grounding.station, Grounding.enabled)
        .join(Frame, Grounding.frame_id == Frame.id)
        .where(Grounding.drive_id == drive.id)
        .order_by(Frame.index)
    )
    return [
        GroundingRow(frame=i, x_m=x, y_m=y, station=st, enabled=on)
        for i, x, y, st, on in session.execute(query).all()
    ]


def export_drive(session: Session, blobs: BlobStore, site: Site, name: str, out_dir: Path) -> Drive:
    """Write a stored drive back as a drive folder (same files, same bytes, same CSV values)."""
    drive = get_drive(session, site, name)
    frames = frame_rows(session, drive)
    extensions = {f.image_ext for f in frames}
    if len(extensions) > 1:
        raise ConflictError(
            f"drive {drive.name!r} mixes image types {sorted(extensions)}; cannot export one folder"
        )
    rows = [
        FrameRow(frame=f.index, t_s=f.t_s, x_m=f.true_x_m, y_m=f.true_y_m, yaw_rad=f.true_yaw_rad)
        for f in frames
    ]

    def images() -> Iterator[bytes]:
        for f in frames:
            yield blobs.get(f.blob_sha256)

    groundings = grounding_rows(session, drive)
    ext = extensions.pop() if extensions else ".png"
    write_drive_folder(out_dir, drive_meta(drive), rows, images(), groundings or None, image_ext=ext)
    return drive


def list_drives(session: Session, site: Site) -> list[DriveSummary]:
    """Every drive of ``site`` with its duration, grounding count and whether it has ground truth."""
    grounding_counts = dict(
        session.execute(
            select(Grounding.drive_id, func.count())
            .join(Drive)
            .where(Drive.site_id == site.id)
            .group_by(Grounding.drive_id)
        ).all()
    )
    spans = {
        drive_id: (t_min, t_max, truth)
        for drive_id, t_min, t_max, truth in session.execute(
            select(Frame.drive_id, func.min(Frame.t_s), func.max(Frame.t_s), func.count(Frame.true_x_m))
            .join(Drive)
            .where(Drive.site_id == site.id)
            .group_by(Frame.drive_id)
        ).all()
    }
    summaries = []
    for drive in session.scalars(select(Drive).where(Drive.site_id == site.id).order_by(Drive.id)):
        t_min, t_max, truth = spans.get(drive.id, (0.0, 0.0, 0))
        summaries.append(
            DriveSummary(
                id=drive.id,
                name=drive.name,
                kind=drive.kind,
                fps=drive.fps,
                frame_count=drive.frame_count,
                duration_s=float(t_max - t_min),
                grounding_count=int(grounding_counts.get(drive.id, 0)),
                has_truth=drive.frame_count > 0 and truth == drive.frame_count,
            )
        )
    return summaries
