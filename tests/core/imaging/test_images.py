"""Tests of driftmap.core.imaging.images: grayscale, crop, down-sample, patch normalisation."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from driftmap.core.imaging.images import crop, downsample, patch_normalise, preprocess, to_gray
from driftmap.core.imaging.params import ImageParams

SEED = 7
MEAN_TOL = 0.05  # |global mean| of patch-normalised random texture
STD_TOL = 0.08  # |global std - 1| of patch-normalised random texture
EXACT_TOL = 1e-4  # float32 box filters against a float64 per-pixel loop


def random_texture(shape: tuple[int, ...], seed: int = SEED) -> np.ndarray:
    return np.random.default_rng(seed).integers(0, 256, size=shape, dtype=np.uint8)


class TestToGray:
    def test_colour_matches_opencv(self) -> None:
        bgr = random_texture((12, 20, 3))
        assert np.array_equal(to_gray(bgr), cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY))

    def test_gray_and_stacks(self) -> None:
        gray = random_texture((3, 12, 20))
        assert to_gray(gray) is gray
        assert to_gray(random_texture((2, 12, 20, 3))).shape == (2, 12, 20)


class TestCrop:
    def test_rect_and_margins_agree(self) -> None:
        img = random_texture((30, 40))
        a = crop(img, rect_px=(5, 3, 30, 20))
        b = crop(img, margins_px=(5, 3, 5, 7))
        assert a.shape == (20, 30) and np.array_equal(a, b)
        assert np.array_equal(a, img[3:23, 5:35])

    def test_stack(self) -> None:
        assert crop(random_texture((4, 30, 40)), rect_px=(0, 0, 10, 5)).shape == (4, 5, 10)

    @pytest.mark.parametrize("rect", [(35, 0, 10, 10), (0, 0, 0, 5), (-1, 0, 5, 5)])
    def test_bad_rect(self, rect: tuple[int, int, int, int]) -> None:
        with pytest.raises(ValueError):
            crop(random_texture((30, 40)), rect_px=rect)

    def test_both_given(self) -> None:
        with pytest.raises(ValueError):
            crop(random_texture((30, 40)), rect_px=(0, 0, 5, 5), margins_px=(0, 0, 0, 0))


class TestDownsample:
    def test_area_average(self) -> None:
        img = random_texture((32, 64))
        small = downsample(img, (16, 8))
        assert small.shape == (8, 16) and small.dtype == np.uint8
        assert abs(int(small[0, 0]) - float(img[:4, :4].mean())) <= 1

    def test_stack_equals_single(self) -> None:
        stack = random_texture((3, 32, 64))
        out = downsample(stack, (16, 8))
        assert out.shape == (3, 8, 16)
        assert np.array_equal(out[1], downsample(stack[1], (16, 8)))


class TestPatchNormalise:
    def test_zero_mean_unit_std_on_texture(self) -> None:
        out = patch_normalise(random_texture((120, 160)), patch_px=8)
        assert out.dtype == np.float32
        assert abs(float(out.mean())) < MEAN_TOL
        assert abs(float(out.std()) - 1.0) < STD_TOL

    def test_flat_image_gives_zeros(self) -> None:
        out = patch_normalise(np.full((40, 50), 77, np.uint8), patch_px=8)
        assert np.all(np.isfinite(out)) and np.all(out == 0.0)

    def test_partly_flat_image_is_finite(self) -> None:
        img = random_texture((40, 50))
        img[:, :25] = 200
        out = patch_normalise(img, patch_px=6)
        assert np.all(np.isfinite(out))
        assert np.all(out[:, :20] == 0.0)

    def test_matches_per_pixel_definition(self) -> None:
        img = random_texture((24, 30)).astype(np.float64)
        patch = 5
        out = patch_normalise(img, patch_px=patch)
        half = patch // 2
        for y in range(half, img.shape[0] - half):
            for x in range(half, img.shape[1] - half):
                window = img[y - half : y + half + 1, x - half : x + half + 1]
                expected = (img[y, x] - window.mean()) / window.std()
                assert abs(out[y, x] - expected) < EXACT_TOL

    def test_stack_equals_single(self) -> None:
        stack = random_texture((3, 20, 30))
        assert np.allclose(patch_normalise(stack)[2], patch_normalise(stack[2]))

    def test_bad_patch(self) -> None:
        with pytest.raises(ValueError):
            patch_normalise(random_texture((10, 10)), patch_px=1)


class TestPreprocess:
    def test_chain(self) -> None:
        frames = random_texture((2, 120, 160, 3))
        params = ImageParams(crop_margins_px=(0, 20, 0, 20), size_px=(64, 32), patch_px=8)
        out = preprocess(frames, params)
        assert out.shape == (2, 32, 64) and out.dtype == np.float32
        assert np.all(np.isfinite(out))
