"""SESAME in localisation: eq. 6 normalisation on hand-made images, query masks, the database selector."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from driftmap.core.imaging.images import preprocess
from driftmap.core.imaging.params import IMAGES_DEFAULT, SadParams
from driftmap.core.localisation.localiser import Localiser
from driftmap.core.localisation.map import LocaliserMap
from driftmap.core.sesame.masks import SESAME_DEFAULT
from driftmap.core.sesame.salient_database import masked_sad
from driftmap.core.topomap.database import (
    DATABASE_OFF,
    DatabaseParams,
    FrameStats,
    database_selector,
    frame_stats,
)
from driftmap.core.topomap.distances import shortest_paths
from driftmap.core.topomap.model import NodeFrames
from driftmap.errors import BadInputError

NO_SHIFT = SadParams(max_shift_x_px=0, max_shift_y_px=0)
TOL = 1e-6


class TestEq6Normalisation:
    def test_mean_over_salient_pixels_only(self) -> None:
        query = np.zeros((4, 8), dtype=np.float32)
        ref = np.full((4, 8), 5.0, dtype=np.float32)  # every plain pixel differs by 5
        mask = np.zeros((4, 8), dtype=bool)
        mask[1, 2:5] = True  # three salient pixels, differing by 2, 2 and 5
        ref[1, 2:4] = 2.0
        d = masked_sad(query, ref[None], mask, NO_SHIFT)
        assert float(d[0]) == pytest.approx((2.0 + 2.0 + 5.0) / 3, abs=TOL)

    def test_same_mean_whatever_the_salient_count(self) -> None:
        query = np.zeros((4, 8), dtype=np.float32)
        ref = np.ones((4, 8), dtype=np.float32)
        small = np.zeros((4, 8), dtype=bool)
        small[0, 0] = True
        large = np.ones((4, 8), dtype=bool)
        for mask in (small, large):
            assert float(masked_sad(query, ref[None], mask, NO_SHIFT)[0]) == pytest.approx(1.0, abs=TOL)

    def test_shift_normalises_by_salient_pixels_in_the_overlap(self) -> None:
        query = np.zeros((2, 4), dtype=np.float32)
        mask = np.zeros((2, 4), dtype=bool)
        mask[:, 3] = True  # the last column: at dx = +1 it has no partner in the reference
        mask[0, 0] = True
        ref = np.full((2, 4), 3.0, dtype=np.float32)
        d = masked_sad(query, ref[None], mask, SadParams(max_shift_x_px=1, max_shift_y_px=0))
        assert float(d[0]) == pytest.approx(
            3.0, abs=TOL
        )  # every overlap gives mean 3 over its salient pixels


def _corridor(n: int, rng: np.random.Generator) -> tuple[np.ndarray, LocaliserMap]:
    """n raw 240x320 frames of distinct textures with a flat (plain) top half, and their map."""
    frames = np.full((n, 240, 320), 100, dtype=np.uint8)
    frames[:, 120:] = rng.integers(0, 256, (n, 120, 320), dtype=np.uint8)
    frames = np.stack([cv2.GaussianBlur(f, (0, 0), 1.0) for f in frames])
    thumbs = preprocess(frames, IMAGES_DEFAULT)
    edges = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1).astype(np.int64)
    lmap = LocaliserMap(
        thumbs=thumbs,
        node_ptr=np.arange(n + 1, dtype=np.int64),
        centres_m=np.column_stack([np.arange(n) * 5.0, np.zeros(n)]),
        adjacency_m=shortest_paths(n, edges, np.full(n - 1, 5.0), 50.0),
        max_adjacency_m=50.0,
    )
    return frames, lmap


class TestLocaliserMasks:
    def test_query_mask_drops_the_plain_half(self) -> None:
        frames, lmap = _corridor(3, np.random.default_rng(1))
        loc = Localiser(lmap, single_image=True, sesame=SESAME_DEFAULT)
        mask = loc.query_mask(frames[0])
        assert mask is not None and mask.shape == (32, 64)
        assert mask[20:].mean() > 0.9 and mask[:12].mean() < 0.1
        assert loc.query_mask(lmap.thumbs[0]) is None  # a thumbnail has no raw pixels
        assert Localiser(lmap, single_image=True).query_mask(frames[0]) is None  # holistic

    def test_flat_frame_falls_back_to_holistic(self) -> None:
        _frames, lmap = _corridor(3, np.random.default_rng(2))
        loc = Localiser(lmap, single_image=True, sesame=SESAME_DEFAULT)
        assert loc.query_mask(np.full((240, 320), 40, dtype=np.uint8)) is None

    def test_masked_localisation_finds_each_node(self) -> None:
        frames, lmap = _corridor(4, np.random.default_rng(3))
        loc = Localiser(lmap, single_image=True, sesame=SESAME_DEFAULT)
        assert [loc.step(f, 0.1 * k).node for k, f in enumerate(frames)] == [0, 1, 2, 3]

    def test_mask_shape_is_checked(self) -> None:
        frames, lmap = _corridor(2, np.random.default_rng(4))
        loc = Localiser(lmap, single_image=True, sesame=SESAME_DEFAULT)
        with pytest.raises(BadInputError, match="mask"):
            loc.step(frames[0], 0.0, mask=np.ones((4, 4), dtype=bool))


def _node(xy: np.ndarray, yaw: np.ndarray) -> NodeFrames:
    c = xy.shape[0]
    return NodeFrames(
        node=0,
        centre_m=xy.mean(axis=0),
        chain=np.zeros(c, dtype=np.int64),
        row=np.arange(c, dtype=np.int64),
        frame_id=np.arange(c, dtype=np.int64),
        xy_m=xy,
        yaw_rad=yaw,
        dist_m=np.linalg.norm(xy - xy.mean(axis=0), axis=1),
        quality=np.zeros(c),
        visit=np.zeros(c, dtype=np.int64),
    )


class TestDatabaseSelector:
    def _stats(self, saliency: np.ndarray, good: np.ndarray) -> tuple[FrameStats, np.ndarray]:
        rng = np.random.default_rng(5)
        thumbs = rng.normal(size=(saliency.size, 32, 64)).astype(np.float32)  # all views distinct
        return FrameStats(saliency, np.ones(thumbs.shape, dtype=bool), good, None), thumbs

    def test_spaced_salient_views_both_directions(self) -> None:
        xy = np.column_stack([np.arange(10) * 0.5, np.zeros(10)])  # a frame every 0.5 m, 4.5 m long
        yaw = np.r_[np.zeros(5), np.full(5, math.pi)]
        sal = np.linspace(0.6, 0.9, 10)
        stats, thumbs = self._stats(sal, np.ones(10, dtype=bool))
        params = DatabaseParams(use_quality=False, view_spacing_m=1.0)
        pick = database_selector(stats, thumbs, np.array([0, 10]), params)([_node(xy, yaw)], 12)[0]
        yaws, picked_xy = yaw[pick], xy[pick]
        assert 0.0 in yaws and math.pi in yaws  # both travel directions kept
        for heading in (0.0, math.pi):
            x = np.sort(picked_xy[yaws == heading, 0])
            assert np.all(np.diff(x) >= 1.0 - TOL)  # views of one direction at least 1 m apart
        assert int(pick[0]) == 9  # the most salient first

    def test_low_saliency_and_bad_frames_are_left_out(self) -> None:
        xy = np.column_stack([np.arange(6) * 2.0, np.zeros(6)])
        sal = np.array([0.9, 0.2, 0.8, 0.7, 0.9, 0.6])  # frame 1 below S_th = 0.5
        good = np.array([True, True, True, False, True, True])  # frame 3 glare
        stats, thumbs = self._stats(sal, good)
        pick = database_selector(stats, thumbs, np.array([0, 6]))([_node(xy, np.zeros(6))], 12)[0]
        assert sorted(pick.tolist()) == [0, 2, 4, 5]

    def test_a_node_with_no_good_frame_keeps_some(self) -> None:
        xy = np.column_stack([np.arange(3) * 2.0, np.zeros(3)])
        stats, thumbs = self._stats(np.full(3, 0.9), np.zeros(3, dtype=bool))
        pick = database_selector(stats, thumbs, np.array([0, 3]))([_node(xy, np.zeros(3))], 12)[0]
        assert pick.size == 3

    def test_off_uses_the_heading_selector_and_k(self) -> None:
        xy = np.column_stack([np.arange(6) * 0.5, np.zeros(6)])
        stats, thumbs = self._stats(np.full(6, 0.9), np.ones(6, dtype=bool))
        select = database_selector(stats, thumbs, np.array([0, 6]), DATABASE_OFF)
        assert select([_node(xy, np.zeros(6))], 2)[0].size == 1  # one visit: one frame


class TestFrameStats:
    def test_saliency_masks_and_classifier(self) -> None:
        rng = np.random.default_rng(6)
        frames = rng.integers(0, 256, (30, 120, 160), dtype=np.uint8)
        frames = np.stack([cv2.GaussianBlur(f, (0, 0), 1.5) for f in frames])
        params = DatabaseParams(quality_sources=4)
        stats = frame_stats([lambda: iter(frames[:20]), lambda: iter(frames[20:])], [20, 10], params)
        assert stats.saliency.shape == (30,) and stats.masks.shape == (30, 32, 64)
        assert stats.classifier is not None and stats.good.shape == (30,)
        assert stats.good.mean() > 0.5  # clean frames of the kind it was trained on

    def test_frame_count_is_checked(self) -> None:
        frames = np.zeros((3, 60, 80), dtype=np.uint8)
        with pytest.raises(BadInputError, match="expected 4"):
            frame_stats([lambda: iter(frames)], [4], DATABASE_OFF)
