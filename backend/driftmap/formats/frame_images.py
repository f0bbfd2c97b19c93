"""Checking and decoding the encoded frame images of a drive (PNG or JPEG, 8-bit).

Decoders can silently accept a file cut short (a PNG missing its last chunks decodes to a partly black
image), so :func:`check_frame_image` also requires the end marker: the PNG ``IEND`` chunk or the JPEG
``EOI`` marker. Images are decoded once and never re-encoded.

A small file can declare a huge image (an 876 KB PNG of 30,000 x 30,000 zero pixels decodes to 900 MB), so
the size is read from the header first (:func:`frame_size`: the PNG ``IHDR`` chunk, the JPEG ``SOF``
marker) and checked before any decoding.
"""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Any, Literal, cast

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.errors import BadInputError, PayloadTooLargeError

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
PNG_IEND = b"\x00\x00\x00\x00IEND\xaeB`\x82"
JPEG_SOI = b"\xff\xd8\xff"
JPEG_EOI = b"\xff\xd9"
_TAIL_BYTES = 4096  # how far from the end an end marker may lie (trailing padding written by some tools)
_JPEG_SOF = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}  # start-of-frame markers (not DHT, JPG, DAC)
_JPEG_STANDALONE = frozenset({0x01, *range(0xD0, 0xD8)})  # TEM and RSTn carry no length


def image_kind(data: bytes) -> Literal["png", "jpeg"] | None:
    """``"png"`` or ``"jpeg"`` from the file's magic bytes, None for anything else."""
    if data.startswith(PNG_MAGIC):
        return "png"
    if data.startswith(JPEG_SOI):
        return "jpeg"
    return None


def check_complete(data: bytes, file: str | Path) -> Literal["png", "jpeg"]:
    """Check the magic bytes and the end marker of an encoded image.

    Returns:
        The kind of image.

    Raises:
        BadInputError: neither PNG nor JPEG, or the end marker is missing (a truncated file).
    """
    kind = image_kind(data)
    if kind is None:
        raise BadInputError("not a PNG or JPEG image", file=file)
    tail_start = max(0, len(data) - _TAIL_BYTES)
    if kind == "png":
        complete = data.endswith(PNG_IEND) or data.rfind(PNG_IEND, tail_start) >= 0
    else:
        complete = data.rstrip(b"\x00\r\n\t ").endswith(JPEG_EOI)
    if not complete:
        marker = "IEND chunk" if kind == "png" else "EOI marker"
        raise BadInputError(f"truncated {kind.upper()} image: no {marker} at the end", file=file)
    return kind


def frame_size(data: bytes, file: str | Path) -> tuple[int, int]:
    """The ``(width, height)`` in pixels an encoded PNG or JPEG declares, read from its header only.

    Raises:
        BadInputError: neither PNG nor JPEG, or no readable size in the header.
    """
    kind = image_kind(data)
    if kind == "png":
        if len(data) < 24 or data[12:16] != b"IHDR":
            raise BadInputError("PNG image without an IHDR header chunk", file=file)
        width, height = struct.unpack(">II", data[16:24])
    elif kind == "jpeg":
        width, height = _jpeg_size(data, file)
    else:
        raise BadInputError("not a PNG or JPEG image", file=file)
    if width < 1 or height < 1:
        raise BadInputError(f"the image header declares a size of {width}x{height} pixels", file=file)
    return int(width), int(height)


def _jpeg_size(data: bytes, file: str | Path) -> tuple[int, int]:
    """Walk the JPEG markers up to the first start-of-frame and read its size."""
    pos = 2
    while pos + 4 <= len(data):
        if data[pos] != 0xFF:
            break
        marker = data[pos + 1]
        if marker == 0xFF:  # fill byte before a marker
            pos += 1
            continue
        if marker in _JPEG_STANDALONE:
            pos += 2
            continue
        if marker in (0xD9, 0xDA):  # end of image or start of scan before any frame header
            break
        (length,) = struct.unpack(">H", data[pos + 2 : pos + 4])
        if marker in _JPEG_SOF:
            if pos + 9 > len(data):
                break
            height, width = struct.unpack(">HH", data[pos + 5 : pos + 9])
            return width, height
        pos += 2 + length
    raise BadInputError("JPEG image without a readable frame header (SOF marker)", file=file)


def check_frame_pixels(
    data: bytes, file: str | Path, max_pixels: int, field: str | None = None
) -> tuple[int, int]:
    """The ``(width, height)`` of an encoded frame, checked against a pixel limit before any decoding.

    Args:
        data: the encoded file bytes (PNG or JPEG).
        file: the file name used in error messages.
        max_pixels: largest accepted width x height, pixels.
        field: the request field the image came from, for the error message.

    Raises:
        PayloadTooLargeError: the header declares more than ``max_pixels`` pixels.
        BadInputError: neither PNG nor JPEG, or no readable size in the header.
    """
    width, height = frame_size(data, file)
    if width * height > max_pixels:
        raise PayloadTooLargeError(
            f"image of {width}x{height} pixels is over the {max_pixels} pixel limit", file=file, field=field
        )
    return width, height


def check_frame_image(data: bytes, file: str | Path, width_px: int, height_px: int) -> NDArray[np.uint8]:
    """Decode one encoded frame and check it is complete, 8-bit and of the camera's size.

    The size is checked from the header before decoding, so a frame of the wrong size costs no memory.

    Args:
        data: the encoded file bytes (PNG or JPEG).
        file: the file name used in error messages.
        width_px: the camera width the frame must have, pixels.
        height_px: the camera height the frame must have, pixels.

    Returns:
        The decoded image, uint8, shape (H, W) for grey or (H, W, C) with C = 3 or 4 (OpenCV BGR order).

    Raises:
        BadInputError: an unreadable or truncated file, a bit depth other than 8, a different size.
    """
    declared = frame_size(data, file)
    if declared != (width_px, height_px):
        raise BadInputError(
            f"frame is {declared[0]}x{declared[1]} pixels but the camera says {width_px}x{height_px}",
            file=file,
        )
    image = _decode(data, file, cv2.IMREAD_UNCHANGED)
    if image.dtype != np.uint8:
        raise BadInputError(f"frames must be 8-bit, this one is {image.dtype}", file=file)
    height, width = image.shape[:2]
    if (width, height) != (width_px, height_px):
        raise BadInputError(
            f"frame is {width}x{height} pixels but the camera says {width_px}x{height_px}", file=file
        )
    return cast(NDArray[np.uint8], image)


def decode_gray(data: bytes, file: str | Path = "<image>") -> NDArray[np.uint8]:
    """Decode a PNG or JPEG to an 8-bit grey image.

    Args:
        data: the encoded file bytes.
        file: the file name used in error messages.

    Returns:
        uint8 array of shape (H, W); colour images are converted with OpenCV's luma weights.

    Raises:
        BadInputError: the bytes are not a complete PNG or JPEG image.
    """
    image = _decode(data, file, cv2.IMREAD_GRAYSCALE)
    return np.ascontiguousarray(image, dtype=np.uint8)


def encode_png(image: NDArray[np.uint8], *, compression: int = 1) -> bytes:
    """Encode an 8-bit image, (H, W) grey or (H, W, 3) BGR, as PNG bytes.

    Args:
        image: the pixels.
        compression: zlib level 0-9; the default favours speed.

    Raises:
        ValueError: not a uint8 grey or 3/4-channel image, or the encoder failed.
    """
    if (
        image.dtype != np.uint8
        or image.ndim not in (2, 3)
        or (image.ndim == 3 and image.shape[2] not in (3, 4))
    ):
        raise ValueError(f"expected a uint8 (H, W) or (H, W, 3|4) image, got {image.dtype} {image.shape}")
    ok, buffer = cv2.imencode(".png", image, [cv2.IMWRITE_PNG_COMPRESSION, int(compression)])
    if not ok:
        raise ValueError("PNG encoding failed")
    return buffer.tobytes()


def _decode(data: bytes, file: str | Path, flags: int) -> NDArray[Any]:
    check_complete(data, file)
    try:
        image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), flags)
    except cv2.error as exc:
        raise BadInputError(f"unreadable image: {str(exc).strip()[:200]}", file=file) from None
    if image is None or image.size == 0:
        raise BadInputError("unreadable image: the decoder rejected it", file=file)
    return image
