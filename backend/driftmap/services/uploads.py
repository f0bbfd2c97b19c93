"""Uploaded files: size-limited saving, drive-folder zips, and drives built frame by frame.

A zip upload is unpacked into a private folder and validated with the drive-folder reader before any job
is queued, so a bad archive is refused with the name of the file inside it (``east.zip: east/frames.csv:17
field 't': ...``). The pixels are checked again by the import itself, which stores nothing on failure.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import zipfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path, PurePosixPath
from typing import BinaryIO

from sqlalchemy import func, select
from sqlalchemy.orm import Session

from driftmap.errors import BadInputError, BadRequestError, ConflictError, PayloadTooLargeError
from driftmap.formats.drive_folder import DriveFolder, read_drive_folder
from driftmap.formats.drive_json import camera_to_json, load_json, parse_camera_block
from driftmap.formats.frame_images import check_complete, check_frame_image
from driftmap.store.blobs import BlobBatch, BlobStore
from driftmap.store.models import Drive, Frame, Site

CHUNK_BYTES = 1024 * 1024
DRIVE_KINDS = ("mapping", "localisation")


def save_upload(source: BinaryIO, dest: Path, *, max_bytes: int, filename: str) -> int:
    """Copy an upload stream to ``dest`` in chunks; returns its size in bytes.

    Raises:
        PayloadTooLargeError: more than ``max_bytes`` (``dest`` is removed).
    """
    size = 0
    try:
        with dest.open("wb") as out:
            while chunk := source.read(CHUNK_BYTES):
                size += len(chunk)
                if size > max_bytes:
                    raise PayloadTooLargeError(
                        f"larger than the {max_bytes} byte upload limit", file=filename
                    )
                out.write(chunk)
    except BaseException:
        dest.unlink(missing_ok=True)
        raise
    return size


def _relabel(exc: BadInputError, root: Path, label: str) -> BadInputError:
    """The same error with paths inside the unpacked folder shown as ``label: inner/path``."""
    file = exc.file
    if file is not None and Path(file).is_relative_to(root):
        file = f"{label}: {Path(file).relative_to(root).as_posix()}"
    elif file is None or Path(file).is_absolute():
        file = label
    return type(exc)(exc.reason, file=file, line=exc.line, field=exc.field)


@contextmanager
def relabelled(root: Path, label: str) -> Iterator[None]:
    """Re-raise a :class:`BadInputError` about a file under ``root`` as one about ``label: inner/path``."""
    try:
        yield
    except BadInputError as exc:
        raise _relabel(exc, root, label) from None


def unpack_drive_zip(zip_path: Path, out_dir: Path, *, label: str, max_bytes: int) -> DriveFolder:
    """Unpack a zipped drive folder into ``out_dir`` and validate it (all but the pixels).

    The archive holds one drive folder, either at its root (``drive.json`` at the top) or as its one
    top-level folder.

    Args:
        zip_path: the uploaded archive.
        out_dir: an empty private folder to unpack into.
        label: the name of the upload used in error messages.
        max_bytes: the largest total unpacked size accepted.

    Raises:
        BadRequestError: not a zip archive, or members escaping the folder.
        PayloadTooLargeError: unpacks to more than ``max_bytes``.
        BadInputError: no drive.json, or a file that breaks the drive-folder format (named inside the zip).
    """
    try:
        archive = zipfile.ZipFile(zip_path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise BadRequestError(f"not a zip archive ({exc})", file=label) from None
    with archive:
        members = [m for m in archive.infolist() if not m.is_dir()]
        if sum(m.file_size for m in members) > max_bytes:
            raise PayloadTooLargeError(f"unpacks to more than the {max_bytes} byte limit", file=label)
        for member in members:
            inner = PurePosixPath(member.filename)
            if inner.is_absolute() or ".." in inner.parts:
                raise BadRequestError(f"member {member.filename!r} points outside the archive", file=label)
        try:
            archive.extractall(out_dir, members)
        except (zipfile.BadZipFile, OSError, EOFError) as exc:
            raise BadRequestError(f"broken zip archive ({exc})", file=label) from None
    candidates = [p.parent for p in out_dir.rglob("drive.json") if "__MACOSX" not in p.parts]
    top = [p for p in candidates if len(p.relative_to(out_dir).parts) <= 1]
    if len(top) != 1:
        what = "no drive.json" if not top else f"{len(top)} drive folders"
        raise BadInputError(
            f"{what} at the top of the archive; zip one drive folder (drive.json, frames.csv, frames/)",
            file=label,
        )
    with relabelled(out_dir, label):
        return read_drive_folder(top[0])


def check_calibration(data: bytes, label: str) -> dict[str, object]:
    """Parse a video's calibration JSON (the ``camera`` block, optionally ``fps``) before queueing it."""
    text = data.decode("utf-8", errors="replace")
    loaded = load_json(text, label)
    if not isinstance(loaded, dict):
        raise BadInputError("calibration must be a JSON object", file=label)
    block = loaded.get("camera", loaded)
    parse_camera_block(block, text, label)
    return loaded


def remove_tree(path: Path) -> None:
    """Delete a scratch folder, ignoring one that is already gone."""
    shutil.rmtree(path, ignore_errors=True)


# ---------------------------------------------------------------------------------------------------
# Drives built frame by frame


def create_empty_drive(
    session: Session, site: Site, *, name: str, kind: str, fps: float, camera: dict[str, object]
) -> Drive:
    """A drive with no frames yet; its camera block is validated as in drive.json."""
    name = name.strip()
    if not name:
        raise BadInputError("a drive needs a non-empty name", field="name")
    if kind not in DRIVE_KINDS:
        raise BadInputError(f"kind must be one of {', '.join(DRIVE_KINDS)}", field="kind")
    if not fps > 0:
        raise BadInputError("fps must be positive", field="fps")
    model = parse_camera_block(camera, "", "camera")
    if session.scalar(select(Drive.id).where(Drive.site_id == site.id, Drive.name == name)) is not None:
        raise ConflictError(f"site {site.name!r} already has a drive named {name!r}")
    drive = Drive(
        site_id=site.id,
        name=name,
        kind=kind,
        fps=fps,
        camera=camera_to_json(model),
        frame_count=0,
        source="api",
    )
    session.add(drive)
    session.flush()
    return drive


def append_frame(
    session: Session, batch: BlobBatch, drive: Drive, data: bytes, *, t_s: float, index: int | None = None
) -> Frame:
    """Add one encoded frame (PNG or JPEG bytes) at time ``t_s`` to the end of ``drive``.

    Args:
        index: the frame number; default one past the last. Must exceed the last one, like ``t_s``.

    Raises:
        BadInputError: not a complete PNG/JPEG of the camera's size; index or time not increasing.
    """
    label = f"frame of drive {drive.name!r}"
    kind = check_complete(data, label)
    check_frame_image(data, label, int(drive.camera["width"]), int(drive.camera["height"]))
    last_index, last_t = session.execute(
        select(func.max(Frame.index), func.max(Frame.t_s)).where(Frame.drive_id == drive.id)
    ).one()
    number = (last_index + 1 if last_index is not None else 0) if index is None else index
    if last_index is not None and number <= last_index:
        raise BadInputError(f"frame number must increase ({number} after {last_index})", field="index")
    if number < 0:
        raise BadInputError("frame number must be >= 0", field="index")
    if last_t is not None and not t_s > last_t:
        raise BadInputError(f"t must increase ({t_s} after {last_t})", field="t")
    frame = Frame(
        drive_id=drive.id,
        index=number,
        t_s=float(t_s),
        blob_sha256=batch.put(data),
        image_ext=".png" if kind == "png" else ".jpg",
    )
    session.add(frame)
    drive.frame_count = (drive.frame_count or 0) + 1
    session.flush()
    return frame


def store_file_as_blob(blobs: BlobStore, path: Path) -> str:
    """Move a file (under the data dir, same file system) into the blob store; returns its SHA-256.

    The file is hashed in chunks, never read whole into memory; ``path`` is gone afterwards.
    """
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        while chunk := handle.read(CHUNK_BYTES):
            digest.update(chunk)
    sha = digest.hexdigest()
    target = blobs.path_of(sha)
    if target.exists():
        path.unlink()
        return sha
    target.parent.mkdir(parents=True, exist_ok=True)
    os.replace(path, target)
    return sha


def scratch_dir(data_dir: Path, prefix: str) -> Path:
    """A new private folder under ``<data_dir>/tmp`` (same file system as the blob store)."""
    root = data_dir / "tmp"
    root.mkdir(parents=True, exist_ok=True)
    return Path(tempfile.mkdtemp(prefix=prefix, dir=root))
