"""Simulated dust and water obscurants ([SSLAM], section IV-A)."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.sim.obscurants import (
    DUST_GREY,
    LEVELS,
    apply_dust,
    apply_level,
    apply_water,
    water_centre,
    water_diameter_px,
    water_mask,
)

H, W = 240, 320


@pytest.fixture
def frame() -> NDArray[np.uint8]:
    """A textured frame with no pixel at the dust grey, so every greyed pixel shows."""
    rng = np.random.default_rng(0)
    img = cv2.GaussianBlur(rng.uniform(0, 255, (H, W)).astype(np.float32), (0, 0), 1.5)
    img = np.clip((img - img.mean()) * 4 + 128, 0, 255).astype(np.uint8)
    img[img == DUST_GREY] = DUST_GREY + 1
    return img


class TestLevels:
    def test_paper_levels(self) -> None:
        assert LEVELS["dust1"].dust_fraction == 0.05 and LEVELS["dust2"].dust_fraction == 0.10
        assert (
            LEVELS["water1"].water_diameter_paper_px == 90 and LEVELS["water2"].water_diameter_paper_px == 150
        )

    def test_water_scales_with_frame_width(self) -> None:
        assert water_diameter_px(90, 944) == 90
        assert water_diameter_px(90, 320) == pytest.approx(90 * 320 / 944)
        assert water_diameter_px(150, 320) == pytest.approx(50.85, abs=0.01)


class TestDust:
    @pytest.mark.parametrize("level", ["dust1", "dust2"])
    def test_exact_share_of_pixels_set_to_grey(self, frame: NDArray[np.uint8], level: str) -> None:
        fraction = LEVELS[level].dust_fraction
        out = apply_level(frame, LEVELS[level], np.random.default_rng(1))
        changed = out != frame
        assert changed.sum() == round(fraction * H * W)
        assert np.all(out[changed] == DUST_GREY)
        assert frame.dtype == out.dtype and not np.shares_memory(frame, out)

    def test_new_pattern_per_seed_same_per_seed(self, frame: NDArray[np.uint8]) -> None:
        a = apply_dust(frame, 0.05, np.random.default_rng(1))
        b = apply_dust(frame, 0.05, np.random.default_rng(1))
        c = apply_dust(frame, 0.05, np.random.default_rng(2))
        assert np.array_equal(a, b) and not np.array_equal(a, c)

    def test_colour_frames_grey_all_channels(self, frame: NDArray[np.uint8]) -> None:
        colour = np.stack([frame, frame // 2, frame // 3 + 1], axis=-1)
        out = apply_dust(colour, 0.1, np.random.default_rng(3))
        changed = np.any(out != colour, axis=-1)
        assert np.all(out[changed] == DUST_GREY)

    def test_bad_fraction(self, frame: NDArray[np.uint8]) -> None:
        with pytest.raises(ValueError):
            apply_dust(frame, 1.5, np.random.default_rng(0))


class TestWater:
    @pytest.mark.parametrize("level", ["water1", "water2"])
    def test_only_the_circle_changes(self, frame: NDArray[np.uint8], level: str) -> None:
        d = water_diameter_px(LEVELS[level].water_diameter_paper_px, W)
        centre = water_centre(frame.shape, d, np.random.default_rng(4))
        out = apply_level(frame, LEVELS[level], np.random.default_rng(5), centre)
        mask = water_mask(frame.shape, d, centre)
        assert np.array_equal(out[~mask], frame[~mask])
        assert (out[mask] != frame[mask]).mean() > 0.8
        assert mask.sum() == pytest.approx(math.pi * d * d / 4, rel=0.05)
        assert out[mask].astype(float).std() < frame[mask].astype(float).std() / 2  # blurred

    def test_static_across_frames(self, frame: NDArray[np.uint8]) -> None:
        d = water_diameter_px(90, W)
        centre = water_centre(frame.shape, d, np.random.default_rng(6))
        rolled = np.roll(frame, 17, axis=1)
        a, b = apply_water(frame, d, centre), apply_water(rolled, d, centre)
        mask = water_mask(frame.shape, d, centre)
        assert np.array_equal(a != frame, (a != frame) & mask)
        assert np.array_equal(b != rolled, (b != rolled) & mask)

    def test_equals_blurring_the_whole_frame(self, frame: NDArray[np.uint8]) -> None:
        d = 50.0
        for centre in ((26.0, 26.0), (160.4, 119.6), (W - 27.0, H - 27.0)):
            full = cv2.GaussianBlur(frame, (0, 0), d / 4, borderType=cv2.BORDER_REFLECT)
            mask = water_mask(frame.shape, d, centre)
            expected = frame.copy()
            expected[mask] = full[mask]
            assert np.array_equal(apply_water(frame, d, centre), expected)

    def test_centre_keeps_the_circle_inside(self) -> None:
        rng = np.random.default_rng(7)
        for _ in range(50):
            x, y = water_centre((H, W), 50.0, rng)
            assert 25.0 <= x <= W - 26.0 and 25.0 <= y <= H - 26.0
        with pytest.raises(ValueError):
            water_centre((H, W), 300.0, rng)

    def test_water_needs_a_centre(self, frame: NDArray[np.uint8]) -> None:
        with pytest.raises(ValueError):
            apply_level(frame, LEVELS["water1"], np.random.default_rng(0))
