"""Files of camera set-up (``docs/formats.md``): ``camera.json`` in progress, floor points, board images.

``camera.json`` holds a ``camera`` block, as the whole object or under a ``"camera"`` key. While a camera is
being set up the block may be partial (only ``width``, ``height`` and ``lens`` after ``driftmap camera
intrinsics``); :func:`complete_camera` validates it once every key of the format is present. The floor
points file is a CSV ``u,v,x,y``: pixel of a floor mark in a recorded frame and its measured floor position
(metres, look frame at the camera's foot: x the way the camera looks, y left); points are numbered 1, 2, ... in file order.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.lens import Lens
from driftmap.core.odometry.camera import CameraModel
from driftmap.errors import BadInputError
from driftmap.formats.bounds import MAX_CAMERA_SIDE_PX
from driftmap.formats.drive_json import (
    CAMERA_KEYS,
    camera_to_json,
    json_text,
    load_json,
    parse_camera_block,
    parse_lens_block,
)
from driftmap.formats.frame_images import decode_gray
from driftmap.formats.tables import decode_text, parse_float, read_table, write_text_atomic

__all__ = [
    "GROUND_POINTS_HEADER",
    "VIDEO_SUFFIXES",
    "calibration_images",
    "complete_camera",
    "lens_of",
    "read_camera_file",
    "read_ground_points",
    "video_frames",
    "write_camera_file",
]

GROUND_POINTS_HEADER: tuple[str, ...] = ("u", "v", "x", "y")
VIDEO_SUFFIXES: tuple[str, ...] = (".mp4", ".avi", ".mkv", ".mov", ".m4v", ".webm")


def _read_text(path: Path, what: str) -> str:
    try:
        return decode_text(path.read_bytes(), path)
    except FileNotFoundError:
        raise BadInputError(f"{what} is missing", file=path) from None
    except OSError as exc:
        raise BadInputError(f"cannot read {what}: {exc.strerror}", file=path) from None


def read_camera_file(path: Path) -> dict[str, Any]:
    """The camera block of a ``camera.json`` as a JSON object, possibly partial.

    Raises:
        BadInputError: a missing or unreadable file, bad JSON, a block that is not an object, or a bad
            ``lens``, ``width`` or ``height``.
    """
    path = Path(path)
    text = _read_text(path, "camera file")
    obj = load_json(text, path)
    block = obj.get("camera", obj) if isinstance(obj, dict) else obj
    if not isinstance(block, dict):
        raise BadInputError("the camera block must be a JSON object", file=path, line=1, field="camera")
    for key in ("width", "height"):
        v = block.get(key)
        if v is not None and (
            isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= MAX_CAMERA_SIDE_PX
        ):
            raise BadInputError(
                f"must be an integer from 1 to {MAX_CAMERA_SIDE_PX} pixels, found {v!r}",
                file=path,
                field=f"camera.{key}",
            )
    if block.get("lens") is not None:
        parse_lens_block(block["lens"], text, path)
    return dict(block)


def complete_camera(block: dict[str, Any], file: str | Path) -> CameraModel | None:
    """The validated camera of a block that has every key of the format, or None while keys are missing.

    Raises:
        BadInputError: a complete block that does not validate (naming ``file`` and the key).
    """
    if any(key not in block for key in CAMERA_KEYS):
        return None
    return parse_camera_block(block, "", file)


def write_camera_file(path: Path, block: dict[str, Any]) -> None:
    """Write a camera block as ``camera.json`` (the block is the whole object), atomically.

    A complete block is validated and written in the format's key order.
    """
    camera = complete_camera(block, path)
    out = camera_to_json(camera) if camera is not None else block
    write_text_atomic(Path(path), json_text(out))


def lens_of(block: dict[str, Any], file: str | Path) -> Lens | None:
    """The lens of a (partial) camera block, or None."""
    return parse_lens_block(block["lens"], "", file) if block.get("lens") is not None else None


def read_ground_points(path: Path) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Read a floor points CSV ``u,v,x,y``.

    Returns:
        ``(N, 2)`` float64 pixels ``(u, v)`` and ``(N, 2)`` float64 floor points ``(x, y)``, metres.

    Raises:
        BadInputError: a missing file, a wrong header, a cell that is not a finite number (file, line, field).
    """
    path = Path(path)
    _, rows = read_table(_read_text(path, "points file"), path, [GROUND_POINTS_HEADER])
    values = [
        [parse_float(r.cells[k], file=path, line=r.line, field=k) for k in GROUND_POINTS_HEADER] for r in rows
    ]
    arr = np.asarray(values, dtype=np.float64).reshape(-1, 4)
    return arr[:, :2].copy(), arr[:, 2:].copy()


def calibration_images(paths: Sequence[Path], every: int = 15) -> Iterator[tuple[str, NDArray[np.uint8]]]:
    """Gray images of a board: image files, or every ``every``-th frame of one video.

    Yields:
        ``(name, image)``: the file name (``video.mp4#frame 30`` for a frame) and a ``(H, W)`` uint8 image.

    Raises:
        BadInputError: a missing or unreadable file, or a video among several inputs.
    """
    videos = [p for p in paths if Path(p).suffix.lower() in VIDEO_SUFFIXES]
    if videos and len(paths) > 1:
        raise BadInputError("give either image files or one video", file=videos[0])
    if videos:
        yield from video_frames(Path(videos[0]), every)
        return
    for p in paths:
        path = Path(p)
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise BadInputError(f"cannot read image: {exc.strerror}", file=path) from None
        yield str(path), decode_gray(data, path)


def video_frames(
    video: Path, every: int = 15, label: str | None = None
) -> Iterator[tuple[str, NDArray[np.uint8]]]:
    """Every ``every``-th frame of a video file, gray.

    Args:
        video: the video file.
        every: keep frames 0, every, 2 * every, ...
        label: the name frames and errors carry (default: the path), e.g. an uploaded file's name.

    Yields:
        ``(name, image)``: ``<label>#frame <index>`` and a ``(H, W)`` uint8 image.

    Raises:
        BadInputError: a missing file or one OpenCV cannot open as a video.
    """
    name = label if label is not None else str(video)
    if not video.is_file():
        raise BadInputError("video is missing", file=name)
    capture = cv2.VideoCapture(str(video))
    if not capture.isOpened():
        capture.release()
        raise BadInputError("not a readable video (OpenCV/FFmpeg cannot open it)", file=name)
    try:
        index = 0
        while True:
            ok, image = capture.read()
            if not ok or image is None:
                return
            if index % max(1, every) == 0:
                gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
                yield f"{name}#frame {index}", np.ascontiguousarray(gray, dtype=np.uint8)
            index += 1
    finally:
        capture.release()
