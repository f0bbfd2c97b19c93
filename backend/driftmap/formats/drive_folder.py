"""Reading and writing a drive folder (``docs/formats.md``)::

    <drive>/drive.json  frames.csv  frames/000000.png ...  [groundings.csv]

:func:`write_drive_folder` builds the folder in a temporary sibling and renames it into place, so a
reader never sees half a drive. :func:`read_drive_folder` validates everything except pixel content;
:func:`iter_frame_images` then checks each frame file (complete, 8-bit, camera-sized) as it yields the
original bytes. Every error is a :class:`BadInputError` naming the file, the 1-based line (the header
of a CSV is line 1) and the field.
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import uuid
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from driftmap.errors import BadInputError, ConflictError
from driftmap.formats.bounds import check_db_int, check_t_s
from driftmap.formats.csv_exports import groundings_text, parse_groundings_rows
from driftmap.formats.drive_json import checked_drive_json, parse_drive_json
from driftmap.formats.frame_images import check_frame_image
from driftmap.formats.records import DriveMeta, FrameRow, GroundingRow
from driftmap.formats.tables import (
    decode_text,
    format_float,
    format_optional_float,
    parse_float,
    parse_int,
    parse_optional_float,
    read_table,
    table_text,
)

log = logging.getLogger(__name__)

FRAMES_HEADER: tuple[str, ...] = ("frame", "t", "x", "y", "yaw")
FRAMES_HEADER_NO_TRUTH: tuple[str, ...] = ("frame", "t")
IMAGE_EXTS: tuple[str, ...] = (".png", ".jpg", ".jpeg")
_FRAME_FILE_RE = re.compile(r"[0-9]+\.(png|jpg|jpeg)", re.IGNORECASE)


@dataclass(frozen=True)
class DriveFolder:
    """A validated drive folder; pixel content is checked later by :func:`iter_frame_images`.

    Attributes:
        path: the folder.
        meta: the contents of ``drive.json``.
        frames: the rows of ``frames.csv`` in file (= time) order.
        frame_files: the image file of each row of ``frames``, same order.
        groundings: the rows of ``groundings.csv``, empty when the file is absent.
    """

    path: Path
    meta: DriveMeta
    frames: list[FrameRow]
    frame_files: list[Path]
    groundings: list[GroundingRow]


def frame_file_name(frame: int, ext: str = ".png") -> str:
    """The file name of frame number ``frame`` inside ``frames/``, e.g. ``000012.png``."""
    return f"{frame:06d}{ext}"


# ----------------------------------------------------------------------------------------------- frames.csv


def frames_text(frames: Iterable[FrameRow]) -> str:
    """``frames.csv`` text, header ``frame,t,x,y,yaw``; ``x,y,yaw`` are empty cells when absent."""
    return table_text(
        FRAMES_HEADER,
        (
            [
                str(int(r.frame)),
                format_float(r.t_s, field="t"),
                format_optional_float(r.x_m, field="x"),
                format_optional_float(r.y_m, field="y"),
                format_optional_float(r.yaw_rad, field="yaw"),
            ]
            for r in frames
        ),
    )


def parse_frames_csv(text: str, file: str | Path) -> list[FrameRow]:
    """Parse and validate ``frames.csv`` text (header ``frame,t,x,y,yaw`` or ``frame,t``).

    Raises:
        BadInputError: a wrong header, a non-integer or negative frame, a non-finite number, partial
            truth, a duplicate frame, ``t`` not increasing, or no rows at all.
    """
    return [row for _, row in _parse_frames(text, file)]


def _parse_frames(text: str, file: str | Path) -> list[tuple[int, FrameRow]]:
    _, table = read_table(text, file, [FRAMES_HEADER, FRAMES_HEADER_NO_TRUTH])
    numbered: list[tuple[int, FrameRow]] = []
    for row in table:
        cells, line = row.cells, row.line
        frame = check_db_int(
            parse_int(cells["frame"], file=file, line=line, field="frame"), "frame", file=file, line=line
        )
        t = check_t_s(parse_float(cells["t"], file=file, line=line, field="t"), "t", file=file, line=line)
        truth = [
            parse_optional_float(cells.get(k, ""), file=file, line=line, field=k) for k in ("x", "y", "yaw")
        ]
        numbered.append((line, FrameRow(frame, t, truth[0], truth[1], truth[2])))
    check_frame_rows(numbered, file)
    return numbered


def check_frame_rows(numbered: Sequence[tuple[int, FrameRow]], file: str | Path) -> None:
    """Check rows that are individually well-formed belong together.

    Args:
        numbered: (1-based line, row) pairs in file order.
        file: the file name used in error messages.

    Raises:
        BadInputError: no rows, a negative or duplicate frame, partial truth, ``t`` not increasing.
    """
    if not numbered:
        raise BadInputError("the drive has no frames", file=file, line=1, field="frame")
    first_line: dict[int, int] = {}
    previous_t: float | None = None
    for line, row in numbered:
        if row.frame < 0:
            raise BadInputError(f"frame number {row.frame} is negative", file=file, line=line, field="frame")
        if row.frame in first_line:
            raise BadInputError(
                f"frame {row.frame} appears twice (first on line {first_line[row.frame]})",
                file=file,
                line=line,
                field="frame",
            )
        first_line[row.frame] = line
        present = [v is not None for v in (row.x_m, row.y_m, row.yaw_rad)]
        if any(present) and not all(present):
            missing = [k for k, p in zip(("x", "y", "yaw"), present, strict=True) if not p]
            raise BadInputError(
                "ground truth must give all of x, y, yaw or none", file=file, line=line, field=missing[0]
            )
        if previous_t is not None and not row.t_s > previous_t:
            raise BadInputError(
                f"t must increase from row to row ({row.t_s!r} after {previous_t!r})",
                file=file,
                line=line,
                field="t",
            )
        previous_t = row.t_s


def _check_groundings(
    groundings: Sequence[GroundingRow], frames: Sequence[FrameRow], file: str | Path, lines: Sequence[int]
) -> None:
    known = {r.frame for r in frames}
    for line, g in zip(lines, groundings, strict=True):
        if g.frame not in known:
            raise BadInputError(f"frame {g.frame} is not in frames.csv", file=file, line=line, field="frame")


# ----------------------------------------------------------------------------------------------- writing


def write_drive_folder(
    out_dir: Path,
    meta: DriveMeta,
    frames: Sequence[FrameRow],
    images: Iterable[bytes],
    groundings: Sequence[GroundingRow] | None = None,
    image_ext: str = ".png",
    *,
    overwrite: bool = False,
) -> None:
    """Write a drive folder atomically.

    Args:
        out_dir: the drive folder to create. Its parent is created if needed.
        meta: the contents of ``drive.json``.
        frames: the rows of ``frames.csv`` in time order.
        images: the already-encoded bytes of each frame's file, in the order of ``frames``; stored
            as ``frames/%06d<image_ext>`` by frame number, not checked or re-encoded.
        groundings: rows of ``groundings.csv``; the file is written only when given.
        image_ext: ``.png``, ``.jpg`` or ``.jpeg``, matching the encoding of ``images``.
        overwrite: replace an existing non-empty ``out_dir`` instead of refusing.

    Raises:
        ConflictError: ``out_dir`` exists, is not empty (or is not a folder) and ``overwrite`` is False.
        BadInputError: rows that a reader would reject, a bad ``fps`` or ``image_ext``, or a number
            of images different from the number of frames.
    """
    out_dir = Path(out_dir)
    ext = image_ext.lower()
    if ext not in IMAGE_EXTS:
        raise BadInputError(f"image_ext must be one of {', '.join(IMAGE_EXTS)}", field="image_ext")
    if out_dir.exists() and not overwrite and (not out_dir.is_dir() or any(out_dir.iterdir())):
        raise ConflictError(f"{out_dir} already exists and is not empty")
    drive_json = checked_drive_json(meta, out_dir / "drive.json")
    check_frame_rows([(i + 2, r) for i, r in enumerate(frames)], out_dir / "frames.csv")
    if groundings is not None:
        _check_groundings(groundings, frames, out_dir / "groundings.csv", range(2, len(groundings) + 2))
    frames_csv = frames_text(frames)
    groundings_csv = groundings_text(groundings) if groundings is not None else None

    out_dir.parent.mkdir(parents=True, exist_ok=True)
    tmp = _fresh_sibling(out_dir, "partial")
    try:
        frames_dir = tmp / "frames"
        frames_dir.mkdir()
        remaining = iter(images)
        for count, row in enumerate(frames):
            data = next(remaining, None)
            if data is None:
                raise BadInputError(
                    f"got {count} images for {len(frames)} frames", file=out_dir / "frames", field="images"
                )
            (frames_dir / frame_file_name(row.frame, ext)).write_bytes(data)
        if next(remaining, None) is not None:
            raise BadInputError(
                f"got more images than the {len(frames)} frames", file=out_dir / "frames", field="images"
            )
        (tmp / "frames.csv").write_text(frames_csv, encoding="utf-8", newline="")
        if groundings_csv is not None:
            (tmp / "groundings.csv").write_text(groundings_csv, encoding="utf-8", newline="")
        (tmp / "drive.json").write_text(drive_json, encoding="utf-8", newline="")
        _move_into_place(tmp, out_dir, overwrite)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def _fresh_sibling(out_dir: Path, suffix: str) -> Path:
    """A new hidden folder beside ``out_dir`` (created with the usual umask, unlike ``mkdtemp``'s 0700)."""
    while True:
        candidate = out_dir.parent / f".{out_dir.name}.{uuid.uuid4().hex[:12]}.{suffix}"
        try:
            candidate.mkdir()
        except FileExistsError:
            continue
        return candidate


def _move_into_place(tmp: Path, out_dir: Path, overwrite: bool) -> None:
    if not out_dir.exists() and not out_dir.is_symlink():
        os.rename(tmp, out_dir)
        return
    if out_dir.is_dir() and not any(out_dir.iterdir()):
        out_dir.rmdir()
        os.rename(tmp, out_dir)
        return
    if not overwrite:
        raise ConflictError(f"{out_dir} already exists and is not empty")
    trash = _fresh_sibling(out_dir, "old")
    os.rename(out_dir, trash / "old")
    os.rename(tmp, out_dir)
    shutil.rmtree(trash, ignore_errors=True)


# ----------------------------------------------------------------------------------------------- reading


def read_drive_folder(path: Path) -> DriveFolder:
    """Read and validate a drive folder, all but the pixels of its frames.

    Args:
        path: the drive folder.

    Raises:
        BadInputError: a missing folder or file, or anything in ``drive.json``, ``frames.csv`` or
            ``groundings.csv`` that breaks the format.
    """
    path = Path(path)
    if not path.is_dir():
        raise BadInputError("drive folder does not exist" if not path.exists() else "not a folder", file=path)
    meta = parse_drive_json(_read_text(path / "drive.json"), path / "drive.json")
    frames_csv = path / "frames.csv"
    numbered = _parse_frames(_read_text(frames_csv), frames_csv)
    frames_dir = path / "frames"
    if not frames_dir.is_dir():
        raise BadInputError("the frames/ folder is missing", file=frames_dir)
    present: dict[str, str] = {}
    for name in os.listdir(frames_dir):
        if _FRAME_FILE_RE.fullmatch(name):
            present[name.lower()] = name
    frame_files: list[Path] = []
    for line, row in numbered:
        found = [present[n] for ext in IMAGE_EXTS if (n := frame_file_name(row.frame, ext)) in present]
        if not found:
            raise BadInputError(
                f"frame file frames/{frame_file_name(row.frame)} (or .jpg/.jpeg) is missing",
                file=frames_csv,
                line=line,
                field="frame",
            )
        if len(found) > 1:
            raise BadInputError(
                f"frame {row.frame} has several files: {', '.join(sorted(found))}",
                file=frames_csv,
                line=line,
                field="frame",
            )
        frame_files.append(frames_dir / found[0])
    unused = len(present) - len(frame_files)
    if unused:
        log.warning("%s: %d image files in frames/ are not named by frames.csv", path, unused)
    groundings: list[GroundingRow] = []
    groundings_csv = path / "groundings.csv"
    if groundings_csv.exists():
        numbered_groundings = parse_groundings_rows(_read_text(groundings_csv), groundings_csv)
        groundings = [g for _, g in numbered_groundings]
        _check_groundings(
            groundings, [r for _, r in numbered], groundings_csv, [n for n, _ in numbered_groundings]
        )
    return DriveFolder(
        path=path,
        meta=meta,
        frames=[r for _, r in numbered],
        frame_files=frame_files,
        groundings=groundings,
    )


def iter_frame_images(folder: DriveFolder) -> Iterator[tuple[FrameRow, bytes]]:
    """Yield each frame's row and original file bytes after checking the file.

    Each file is decoded once (to catch corrupt data) and never re-encoded.

    Raises:
        BadInputError: naming the file, when it is unreadable, truncated, not 8-bit, or not of the
            camera's width x height.
    """
    width, height = folder.meta.camera.width_px, folder.meta.camera.height_px
    for row, file in zip(folder.frames, folder.frame_files, strict=True):
        try:
            data = file.read_bytes()
        except OSError as exc:
            raise BadInputError(f"cannot read frame file: {exc.strerror}", file=file) from None
        check_frame_image(data, file, width, height)
        yield row, data


def _read_text(file: Path) -> str:
    try:
        data = file.read_bytes()
    except FileNotFoundError:
        raise BadInputError("file is missing", file=file) from None
    except OSError as exc:
        raise BadInputError(f"cannot read file: {exc.strerror}", file=file) from None
    return decode_text(data, file)
