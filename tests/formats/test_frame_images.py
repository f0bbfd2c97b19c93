"""Tests of driftmap.formats.frame_images: completeness, bit depth, size, grey decoding."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from driftmap.errors import BadInputError
from driftmap.formats.frame_images import (
    check_complete,
    check_frame_image,
    decode_gray,
    encode_png,
    image_kind,
)
from tests.formats.builders import HEIGHT_PX, WIDTH_PX, make_jpeg, make_png


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
