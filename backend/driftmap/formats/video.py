"""A drive recorded as a video file (mp4, avi, anything OpenCV's FFmpeg backend reads) plus a calibration.

The calibration JSON holds the ``camera`` block of ``drive.json`` (``docs/formats.md``), either as the
whole object or under a ``"camera"`` key, and an optional ``"fps"`` that overrides the frame rate the
video container claims. Frames become PNG files: grey when the video is grey, colour otherwise.

Frame times ``t`` (seconds since the first frame) come from the decoder's per-frame timestamps when they
are finite and strictly increasing, else from ``index / fps``; with an ``fps`` override always from
``index / fps``.
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.odometry.camera import CameraModel
from driftmap.errors import BadInputError
from driftmap.formats.drive_json import load_json, parse_camera_block
from driftmap.formats.frame_images import encode_png
from driftmap.formats.records import DRIVE_KINDS, DriveKind, DriveMeta, FrameRow
from driftmap.formats.tables import decode_text

log = logging.getLogger(__name__)

VIDEO_SUFFIXES: tuple[str, ...] = (".mp4", ".avi", ".mov", ".mkv", ".m4v")
_MAX_FPS = 1000.0  # frame rates above this are taken as a broken container header
_GREY_TOLERANCE = 2  # max difference between colour channels (of 255) for a frame to count as grey


def read_calibration_json(path: Path) -> tuple[CameraModel, float | None]:
    """Read a calibration file: the camera block and an optional fps override.

    Args:
        path: the JSON file, ``{"width": ..., ...}`` or ``{"camera": {...}, "fps": 10.0}``.

    Returns:
        The camera and the fps override in frames per second (None when absent).

    Raises:
        BadInputError: a missing or unreadable file, bad JSON, a bad camera block or fps.
    """
    path = Path(path)
    try:
        text = decode_text(path.read_bytes(), path)
    except FileNotFoundError:
        raise BadInputError("calibration file is missing", file=path) from None
    except OSError as exc:
        raise BadInputError(f"cannot read calibration file: {exc.strerror}", file=path) from None
    obj = load_json(text, path)
    if not isinstance(obj, dict):
        raise BadInputError("calibration must be a JSON object", file=path, line=1)
    block: Any = obj.get("camera", obj)
    camera = parse_camera_block(block, text, path)
    fps_value = obj.get("fps", block.get("fps") if isinstance(block, dict) else None)
    if fps_value is None:
        return camera, None
    if (
        isinstance(fps_value, bool)
        or not isinstance(fps_value, int | float)
        or not math.isfinite(fps_value)
        or fps_value <= 0
    ):
        line = next((i + 1 for i, t in enumerate(text.split("\n")) if '"fps"' in t), None)
        raise BadInputError(
            f"fps must be a finite positive number, found {fps_value!r}", file=path, line=line, field="fps"
        )
    return camera, float(fps_value)


def read_video_drive(
    video: Path, calibration_json: Path | CameraModel, *, name: str, kind: str
) -> tuple[DriveMeta, list[FrameRow], Iterator[bytes]]:
    """Read a video drive: its metadata and frame rows now, its PNG frames lazily.

    The video is scanned once here (to count frames and read timestamps) and decoded again by the
    returned iterator, so memory stays flat for long videos.

    Args:
        video: the video file.
        calibration_json: the calibration file (see :func:`read_calibration_json`), or the camera itself.
        name: the drive name.
        kind: ``"mapping"`` or ``"localisation"``.

    Returns:
        The drive metadata, one :class:`FrameRow` per video frame (frame = 0-based index, no truth),
        and an iterator of PNG bytes in the same order, each ``camera.width x camera.height``.

    Raises:
        BadInputError: a bad name, kind or calibration, an unreadable video, a video with no frames or
            no usable frame rate, or frames whose size disagrees with the calibration. The iterator raises
            it too if the video decodes differently the second time.
    """
    video = Path(video)
    if not name.strip():
        raise BadInputError("the drive name must not be empty", field="name")
    if kind not in DRIVE_KINDS:
        raise BadInputError(f"kind must be one of {', '.join(DRIVE_KINDS)}, got {kind!r}", field="kind")
    if isinstance(calibration_json, CameraModel):
        camera, fps_override = calibration_json, None
    else:
        camera, fps_override = read_calibration_json(calibration_json)
    if not video.is_file():
        raise BadInputError("video file is missing", file=video)

    capture = _open(video)
    try:
        width = int(capture.get(cv2.CAP_PROP_FRAME_WIDTH))
        height = int(capture.get(cv2.CAP_PROP_FRAME_HEIGHT))
        container_fps = float(capture.get(cv2.CAP_PROP_FPS))
        stamps_ms: list[float] = []
        while capture.grab():
            stamps_ms.append(float(capture.get(cv2.CAP_PROP_POS_MSEC)))
    finally:
        capture.release()
    if not stamps_ms:
        raise BadInputError("the video has no frames", file=video)
    if width > 0 and height > 0 and (width, height) != (camera.width_px, camera.height_px):
        raise BadInputError(
            f"video frames are {width}x{height} pixels but the calibration says "
            f"{camera.width_px}x{camera.height_px}",
            file=video,
            field="width",
        )
    fps = fps_override if fps_override is not None else container_fps
    if not (math.isfinite(fps) and 0 < fps <= _MAX_FPS):
        raise BadInputError(
            f"the video gives no usable frame rate ({container_fps!r}); add 'fps' to the calibration",
            file=video,
            field="fps",
        )
    times = _frame_times(stamps_ms, fps, use_stamps=fps_override is None)
    rows = [FrameRow(frame=i, t_s=t) for i, t in enumerate(times)]
    meta = DriveMeta(name=name, kind=cast(DriveKind, kind), fps=fps, camera=camera)
    return meta, rows, _png_frames(video, len(rows), camera)


def _frame_times(stamps_ms: list[float], fps: float, *, use_stamps: bool) -> list[float]:
    """Seconds since the first frame: decoder timestamps when sane, else index / fps."""
    sane = all(math.isfinite(s) for s in stamps_ms) and all(b > a for a, b in itertools.pairwise(stamps_ms))
    if use_stamps and sane and len(stamps_ms) > 1:
        return [(s - stamps_ms[0]) / 1000.0 for s in stamps_ms]
    if use_stamps and len(stamps_ms) > 1:
        log.info("video timestamps are not increasing; using frame index / %.3f fps", fps)
    return [i / fps for i in range(len(stamps_ms))]


def _png_frames(video: Path, count: int, camera: CameraModel) -> Iterator[bytes]:
    capture = _open(video)
    try:
        for index in range(count):
            ok, image = capture.read()
            if not ok or image is None:
                raise BadInputError(f"frame {index} could not be decoded (the video ended early)", file=video)
            yield encode_png(_to_storage_pixels(image, video, index, camera))
    finally:
        capture.release()


def _to_storage_pixels(
    image: NDArray[Any], video: Path, index: int, camera: CameraModel
) -> NDArray[np.uint8]:
    """A decoded (H, W, 3) BGR frame as stored: (H, W) grey when its channels agree, else unchanged."""
    if image.dtype != np.uint8:
        raise BadInputError(f"frame {index} is {image.dtype}, not 8-bit", file=video)
    height, width = image.shape[:2]
    if (width, height) != (camera.width_px, camera.height_px):
        raise BadInputError(
            f"frame {index} is {width}x{height} pixels but the calibration says "
            f"{camera.width_px}x{camera.height_px}",
            file=video,
        )
    if image.ndim == 2:
        return cast(NDArray[np.uint8], image)
    channels = image[:, :, :3].astype(np.int16)
    spread = int(np.abs(channels - channels[:, :, 1:2]).max())
    if spread <= _GREY_TOLERANCE:
        return cast(NDArray[np.uint8], cv2.cvtColor(image[:, :, :3], cv2.COLOR_BGR2GRAY))
    return cast(NDArray[np.uint8], image)


def _open(video: Path) -> cv2.VideoCapture:
    capture = cv2.VideoCapture(str(video))
    if not capture.isOpened():
        capture.release()
        raise BadInputError("not a readable video (OpenCV/FFmpeg cannot open it)", file=video)
    return capture
