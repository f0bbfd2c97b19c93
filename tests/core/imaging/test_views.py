"""Tests of driftmap.core.imaging.views: a camera's thumbnail view and the thumbnails taken of it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from driftmap.core.imaging.images import preprocess
from driftmap.core.imaging.lens import Lens
from driftmap.core.imaging.params import IMAGES_DEFAULT, IMAGES_FAST, SAD_DEFAULT, ImageParams
from driftmap.core.imaging.sad import sad_one_to_many
from driftmap.core.imaging.views import (
    VIEW_MAX_HFOV_DEG,
    ViewMaps,
    thumbnails,
    undistorted_view,
    view_maps,
    view_matrix,
)
from driftmap.errors import BadInputError
from tests.core.imaging.boards import FISHEYE, PINHOLE, SIZE, render_wall, wall_texture

VIEW_SAD_TOL = (
    0.05  # patch-normalised units: the view's thumbnail against the ideal one (measured 0.002-0.005)
)
RAW_GAIN = 20.0  # the raw frame's thumbnail is at least this many times farther from the ideal one (measured
#                  >100x)
N_FRAMES = 25  # frames thumbnailed while counting table builds


def ideal_lens(lens: Lens) -> Lens:
    """The distortion-free pinhole of ``lens``'s thumbnail view."""
    k = view_matrix(lens, SIZE)
    return Lens("pinhole", tuple(tuple(float(v) for v in row) for row in k), (0.0, 0.0, 0.0, 0.0))


@pytest.fixture(scope="module")
def texture() -> np.ndarray:
    return wall_texture()


class TestViewMatrix:
    def test_an_ordinary_lens_keeps_its_matrix(self) -> None:
        np.testing.assert_array_equal(view_matrix(PINHOLE, SIZE), PINHOLE.matrix())  # 75 degrees across

    def test_a_strong_fisheye_is_narrowed_to_the_widest_view(self) -> None:
        k = view_matrix(FISHEYE, SIZE)  # its K as a pinhole spans 119 degrees across
        assert 2 * math.degrees(math.atan(SIZE[0] / 2 / k[0, 0])) == pytest.approx(VIEW_MAX_HFOV_DEG)
        assert k[0, 0] == pytest.approx(k[1, 1])  # square pixels stay square
        assert (k[0, 2], k[1, 2]) == (FISHEYE.K[0][2], FISHEYE.K[1][2])  # the principal point stays


class TestThumbnails:
    @pytest.mark.parametrize("lens", [PINHOLE, FISHEYE], ids=["pinhole", "fisheye"])
    def test_the_view_matches_the_ideal_frame(self, texture: np.ndarray, lens: Lens) -> None:
        raw = render_wall(lens, texture)
        ideal = preprocess(render_wall(ideal_lens(lens), texture), IMAGES_DEFAULT)
        candidates = np.stack([thumbnails(raw, IMAGES_DEFAULT, lens), preprocess(raw, IMAGES_DEFAULT)])
        d_view, d_raw = sad_one_to_many(ideal, candidates, SAD_DEFAULT).d
        assert d_view < VIEW_SAD_TOL
        assert d_raw > RAW_GAIN * d_view

    @pytest.mark.parametrize(
        "params", [IMAGES_DEFAULT, IMAGES_FAST, ImageParams(crop_margins_px=(10, 20, 30, 40), size_px=None)]
    )
    def test_without_a_lens_they_are_the_preprocessed_frames(
        self, texture: np.ndarray, params: ImageParams
    ) -> None:
        frames = np.stack([render_wall(PINHOLE, texture, distance_m=d) for d in (1.0, 1.3)])
        np.testing.assert_array_equal(thumbnails(frames, params, None), preprocess(frames, params))
        first = frames[0]
        np.testing.assert_array_equal(thumbnails(first, params, None), preprocess(first, params))
        assert undistorted_view(first, None) is first

    def test_an_undistorted_pinhole_needs_no_view(self, texture: np.ndarray) -> None:
        plain = Lens("pinhole", PINHOLE.K, (0.0, 0.0, 0.0, 0.0))
        frame = render_wall(PINHOLE, texture)
        assert ViewMaps(plain, SIZE).identity and not ViewMaps(PINHOLE, SIZE).identity
        assert undistorted_view(frame, plain) is frame
        np.testing.assert_array_equal(
            thumbnails(frame, IMAGES_DEFAULT, plain), preprocess(frame, IMAGES_DEFAULT)
        )

    def test_stacks_colour_and_single_frames_agree(self, texture: np.ndarray) -> None:
        frames = np.stack([render_wall(FISHEYE, texture, distance_m=d) for d in (1.0, 1.3)])
        stack = thumbnails(frames, IMAGES_DEFAULT, FISHEYE)
        np.testing.assert_array_equal(stack[1], thumbnails(frames[1], IMAGES_DEFAULT, FISHEYE))
        colour = np.repeat(frames[0][..., None], 3, axis=2)
        np.testing.assert_array_equal(stack[0], thumbnails(colour, IMAGES_DEFAULT, FISHEYE))


class TestTables:
    def test_built_once_for_many_frames(self, texture: np.ndarray) -> None:
        frame = render_wall(FISHEYE, texture)
        view_maps.cache_clear()
        for _ in range(N_FRAMES):
            thumbnails(frame, IMAGES_DEFAULT, FISHEYE)
        thumbnails(np.stack([frame, frame]), IMAGES_DEFAULT, FISHEYE)
        info = view_maps.cache_info()
        assert (info.misses, info.hits) == (1, N_FRAMES + 1)

    def test_keyed_by_lens_and_frame_size(self, texture: np.ndarray) -> None:
        view_maps.cache_clear()
        undistorted_view(render_wall(FISHEYE, texture), FISHEYE)
        undistorted_view(render_wall(PINHOLE, texture), PINHOLE)
        undistorted_view(np.zeros((240, 320), dtype=np.uint8), PINHOLE)
        assert view_maps.cache_info().misses == 3

    def test_frame_size_is_checked(self) -> None:
        with pytest.raises(BadInputError, match="frame"):
            ViewMaps(PINHOLE, SIZE).apply(np.zeros((10, 10), dtype=np.uint8))
