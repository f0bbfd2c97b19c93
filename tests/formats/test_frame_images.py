"""Tests of driftmap.formats.frame_images: completeness, bit depth, size, grey decoding."""

from __future__ import annotations

import struct
import time

import cv2
import numpy as np
import pytest

from driftmap.errors import BadInputError, PayloadTooLargeError
from driftmap.formats.frame_images import (
    check_complete,
    check_frame_image,
    check_frame_pixels,
    decode_gray,
    encode_png,
    frame_size,
    image_kind,
)
from tests.formats.builders import HEIGHT_PX, WIDTH_PX, make_jpeg, make_png
from tests.image_bombs import zero_png

BOMB_SIDE_PX = 30_000  # 900 MB of pixels in a 0.9 MB file
REFUSED_WITHIN_S = 10.0  # a guard against the defects fixed (a minute and gigabytes), not a speed figure


def error_of(data: bytes, width: int = WIDTH_PX, height: int = HEIGHT_PX) -> BadInputError:
    with pytest.raises(BadInputError) as info:
        check_frame_image(data, "frames/000001.png", width, height)
    assert info.value.file == "frames/000001.png"
    return info.value


class TestKinds:
    def test_magic_bytes(self) -> None:
        assert image_kind(make_png(0)) == "png"
        assert image_kind(make_jpeg(0)) == "jpeg"
        assert image_kind(b"GIF89a") is None

    def test_jpeg_with_trailing_padding_is_complete(self) -> None:
        assert check_complete(make_jpeg(0) + b"\x00\x00", "f.jpg") == "jpeg"


class TestTruncatedOrCorrupt:
    @pytest.mark.parametrize("keep", [0.5, 0.9])
    def test_cut_png(self, keep: float) -> None:
        data = make_png(1)
        assert "truncated PNG" in error_of(data[: int(len(data) * keep)]).reason

    def test_png_without_its_iend_chunk(self) -> None:
        assert "IEND" in error_of(make_png(1)[:-12]).reason

    def test_cut_jpeg(self) -> None:
        data = make_jpeg(1)
        assert "truncated JPEG" in error_of(data[: len(data) // 2]).reason

    def test_png_with_corrupt_pixel_data(self) -> None:
        data = bytearray(make_png(1))
        data[100:110] = bytes(10)
        assert "unreadable" in error_of(bytes(data)).reason

    def test_empty_file(self) -> None:
        assert "not a PNG or JPEG" in error_of(b"").reason


class TestDepthAndSize:
    def test_sixteen_bit_png_is_refused(self) -> None:
        ok, buf = cv2.imencode(".png", np.zeros((HEIGHT_PX, WIDTH_PX), np.uint16))
        assert ok
        assert "8-bit" in error_of(buf.tobytes()).reason

    def test_other_size_names_both_sizes(self) -> None:
        err = error_of(make_png(0, width=WIDTH_PX, height=HEIGHT_PX + 1))
        assert f"{WIDTH_PX}x{HEIGHT_PX + 1}" in err.reason and f"{WIDTH_PX}x{HEIGHT_PX}" in err.reason

    @pytest.mark.parametrize("channels", [1, 3, 4])
    def test_returns_the_decoded_pixels(self, channels: int) -> None:
        image = check_frame_image(make_png(3, channels=channels), "f", WIDTH_PX, HEIGHT_PX)
        assert image.dtype == np.uint8
        assert image.shape[:2] == (HEIGHT_PX, WIDTH_PX)
        assert (image.ndim == 2) == (channels == 1)


def _jpeg_declaring(width: int, height: int) -> bytes:
    """A small real JPEG whose frame header (SOF) is patched to declare ``width`` x ``height``."""
    data = bytearray(make_jpeg(2))
    sof = data.index(b"\xff\xc0")
    data[sof + 5 : sof + 9] = struct.pack(">HH", height, width)
    return bytes(data)


class TestSizeFromTheHeader:
    @pytest.mark.parametrize("make", [make_png, make_jpeg])
    def test_size_of_real_images(self, make: object) -> None:
        assert frame_size(make(0, width=45, height=17), "f") == (45, 17)  # type: ignore[operator]

    def test_jpeg_size_is_read_past_other_segments(self) -> None:
        ok, buf = cv2.imencode(".jpg", np.zeros((9, 13, 3), np.uint8), [cv2.IMWRITE_JPEG_PROGRESSIVE, 1])
        assert ok
        assert frame_size(buf.tobytes(), "f") == (13, 9)

    def test_a_header_without_a_size_is_refused(self) -> None:
        with pytest.raises(BadInputError, match="SOF"):
            frame_size(b"\xff\xd8\xff\xd9", "f.jpg")
        with pytest.raises(BadInputError, match="IHDR"):
            frame_size(make_png(0)[:20], "f.png")

    @pytest.mark.parametrize(
        "make", [lambda: zero_png(BOMB_SIDE_PX, BOMB_SIDE_PX), lambda: _jpeg_declaring(60_000, 60_000)]
    )
    def test_a_bomb_is_refused_by_its_header_at_once(self, make: object) -> None:
        data = make()  # type: ignore[operator]
        start = time.perf_counter()
        with pytest.raises(PayloadTooLargeError, match="pixel limit") as info:
            check_frame_pixels(data, "frame", 4096 * 4096, field="body")
        assert time.perf_counter() - start < REFUSED_WITHIN_S
        assert info.value.field == "body"

    def test_a_frame_within_the_limit_passes(self) -> None:
        assert check_frame_pixels(make_png(0), "f", WIDTH_PX * HEIGHT_PX) == (WIDTH_PX, HEIGHT_PX)

    def test_a_bomb_of_the_wrong_size_is_refused_before_decoding(self) -> None:
        data = zero_png(BOMB_SIDE_PX, BOMB_SIDE_PX)
        start = time.perf_counter()
        err = error_of(data)
        assert time.perf_counter() - start < REFUSED_WITHIN_S
        assert f"{BOMB_SIDE_PX}x{BOMB_SIDE_PX}" in err.reason


class TestDecodeGray:
    def test_grey_png_is_lossless(self) -> None:
        pixels = np.random.default_rng(5).integers(0, 256, (7, 9), dtype=np.uint8)
        assert np.array_equal(decode_gray(encode_png(pixels)), pixels)

    def test_colour_becomes_grey(self) -> None:
        image = decode_gray(make_png(2, channels=3))
        assert image.shape == (HEIGHT_PX, WIDTH_PX) and image.dtype == np.uint8

    def test_broken_data_names_the_source(self) -> None:
        with pytest.raises(BadInputError, match=r"query/a\.png"):
            decode_gray(b"\x89PNG\r\n\x1a\nrest", "query/a.png")


class TestEncodePng:
    def test_refuses_float_images(self) -> None:
        with pytest.raises(ValueError, match="uint8"):
            encode_png(np.zeros((4, 4), np.float32))
