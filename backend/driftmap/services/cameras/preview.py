"""Previews of a camera in set-up: a frame's undistorted image and the bird's-eye view of its floor.

A surveyor checks a lens and a ground fit by eye before saving them: straight edges of the scene must be
straight in the undistorted image (``core.imaging.lens.undistort_image``: the ideal pinhole image of the same
size and ``K``, the image the ground ROI and homography refer to), and the floor must look like a plan in the
bird's-eye view (``core.odometry.birdseye``): square tiles square, known lengths at their length, x the way the
camera looks pointing up. :func:`make_preview` takes one encoded frame and a camera block in progress
(``docs/formats.md``: ``width``, ``height``, optional ``lens``, ``ground_roi``, ``ground_homography``; other keys
are ignored) and answers both images as PNG. Errors are :class:`~driftmap.errors.BadInputError` naming the
field: ``frame`` (not an image, a size other than the block's) or ``camera.<key>``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.lens import Lens, undistort_image
from driftmap.core.odometry.birdseye import BirdsEye, birdseye_view
from driftmap.core.odometry.grid import Rect
from driftmap.errors import BadInputError
from driftmap.formats.bounds import MAX_CAMERA_SIDE_PX
from driftmap.formats.drive_json import load_json
from driftmap.formats.frame_images import check_frame_pixels, encode_png
from driftmap.services.cameras.calibration import choose_roi, decode_images, parse_lens

__all__ = ["Preview", "PreviewCamera", "make_preview", "parse_preview_camera"]


@dataclass(frozen=True)
class PreviewCamera:
    """The keys of a camera block in progress that a preview needs.

    Attributes:
        width_px: frame width, pixels.
        height_px: frame height, pixels.
        lens: the lens, or None (the frame is its own undistorted image).
        ground_roi: ``(x, y, w, h)`` ground ROI of the undistorted image, pixels, or None.
        homography: ``(3, 3)`` ground homography (undistorted pixel -> floor, look frame, metres), or None.
    """

    width_px: int
    height_px: int
    lens: Lens | None = None
    ground_roi: Rect | None = None
    homography: tuple[tuple[float, float, float], ...] | None = None


@dataclass(frozen=True)
class Preview:
    """The previews of one frame.

    Attributes:
        width_px: width of the frame and of its undistorted image, pixels.
        height_px: height, pixels.
        undistorted_png: the undistorted image, grey PNG (the frame itself, grey, without a lens).
        birdseye: the bird's-eye view, when the block has a ground homography.
        birdseye_png: its image as grey PNG.
    """

    width_px: int
    height_px: int
    undistorted_png: bytes
    birdseye: BirdsEye | None = None
    birdseye_png: bytes | None = None


def _integer(block: dict[str, object], key: str, field: str) -> int:
    value = block.get(key)
    if isinstance(value, bool) or not isinstance(value, int):
        raise BadInputError(f"must be an integer, found {value!r:.60}", field=f"{field}.{key}")
    if not 1 <= value <= MAX_CAMERA_SIDE_PX:
        raise BadInputError(
            f"must be 1 to {MAX_CAMERA_SIDE_PX} pixels, found {value}", field=f"{field}.{key}"
        )
    return value


def _number(value: object) -> bool:
    return not isinstance(value, bool) and isinstance(value, int | float) and math.isfinite(value)


def parse_preview_camera(text: str, field: str = "camera") -> PreviewCamera:
    """Read a camera block in progress (JSON text of an object) for a preview.

    Raises:
        BadInputError: text that is not a JSON object, a width or height that is not 1 to
            ``MAX_CAMERA_SIDE_PX``, a bad lens, an ROI outside the frame, a homography that is not 3x3 finite
            numbers or given without an ROI; the field is ``<field>.<key>`` (``camera.lens.K``, ...).
    """
    try:
        block = load_json(text, field)
    except BadInputError as exc:
        raise BadInputError(exc.reason, line=exc.line, field=field) from None
    if not isinstance(block, dict):
        raise BadInputError("must be a JSON object (a camera block)", field=field)
    width, height = _integer(block, "width", field), _integer(block, "height", field)
    lens = parse_lens(block["lens"], f"{field}.lens") if block.get("lens") is not None else None
    roi: Rect | None = None
    if block.get("ground_roi") is not None:
        given = block["ground_roi"]
        if (
            not isinstance(given, list)
            or len(given) != 4
            or not all(isinstance(v, int) and not isinstance(v, bool) for v in given)
        ):
            raise BadInputError(
                f"must be 4 integers [x, y, w, h], found {given!r:.60}", field=f"{field}.ground_roi"
            )
        roi = choose_roi(given, width, height, np.zeros((0, 2)), f"{field}.ground_roi")
    hom: tuple[tuple[float, float, float], ...] | None = None
    if block.get("ground_homography") is not None:
        rows = block["ground_homography"]
        if not (
            isinstance(rows, list)
            and len(rows) == 3
            and all(isinstance(r, list) and len(r) == 3 and all(_number(v) for v in r) for r in rows)
        ):
            raise BadInputError("must be a 3x3 list of finite numbers", field=f"{field}.ground_homography")
        if roi is None:
            raise BadInputError("is needed with a ground_homography", field=f"{field}.ground_roi")
        hom = tuple((float(r[0]), float(r[1]), float(r[2])) for r in rows)
    return PreviewCamera(width, height, lens, roi, hom)


def _decode_frame(data: bytes, name: str, camera: PreviewCamera, max_pixels: int) -> NDArray[np.uint8]:
    """The frame as ``(H, W)`` uint8 grey, its size checked from its header before decoding."""
    try:
        size = check_frame_pixels(data, name, max_pixels, "frame")
    except BadInputError as exc:
        raise type(exc)(exc.reason, file=name, field="frame") from None
    if size != (camera.width_px, camera.height_px):
        raise BadInputError(
            f"is {size[0]}x{size[1]} pixels but the camera block says {camera.width_px}x{camera.height_px}",
            file=name,
            field="frame",
        )
    _name, gray = next(decode_images([(name, data)], field="frame"))
    return gray


def make_preview(
    data: bytes, name: str, camera: PreviewCamera, max_pixels: int, field: str = "camera"
) -> Preview:
    """The undistorted image of an encoded frame and, with a ground homography, its bird's-eye view.

    Args:
        data: the frame, PNG or JPEG bytes, as recorded (raw, distorted).
        name: the frame's file name, for errors.
        camera: the block in progress (:func:`parse_preview_camera`).
        max_pixels: largest frame accepted, width x height pixels (checked before decoding).
        field: the camera block's field name in errors.

    Raises:
        BadInputError: not a PNG or JPEG image, or not ``width`` x ``height`` (field ``frame``); a ground ROI
            reaching above the horizon of the homography (``camera.ground_roi``) or a singular homography
            (``camera.ground_homography``).
        PayloadTooLargeError: a frame of more than ``max_pixels`` pixels.
    """
    gray = _decode_frame(data, name, camera, max_pixels)
    undistorted = undistort_image(camera.lens, gray) if camera.lens is not None else gray
    birdseye = None
    if camera.homography is not None and camera.ground_roi is not None:
        try:
            birdseye = birdseye_view(undistorted, np.asarray(camera.homography), camera.ground_roi)
        except BadInputError as exc:
            raise BadInputError(exc.reason, field=f"{field}.{exc.field}") from None
    return Preview(
        camera.width_px,
        camera.height_px,
        encode_png(undistorted),
        birdseye,
        encode_png(birdseye.image) if birdseye is not None else None,
    )
