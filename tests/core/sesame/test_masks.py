"""Tests of SESAME saliency masks, the Saliency Score and Algorithm 1 ([SESAME], sections 3.2-3.4)."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from driftmap.core.imaging.images import patch_normalise
from driftmap.core.imaging.params import ImageParams, SadParams
from driftmap.core.imaging.sad import sad_pairs
from driftmap.core.sesame.masks import (
    SESAME_DEFAULT,
    SESAME_PAPER,
    SesameParams,
    combine_masks,
    entropy_mask,
    frame_saliency,
    patch_entropy,
    saliency_score,
    saliency_score_max,
    sesame_masks,
)
from driftmap.core.sesame.salient_database import (
    PairScores,
    build_salient_database,
    build_salient_databases,
    masked_sad,
)
from driftmap.core.topomap.build import build_topomap
from driftmap.core.topomap.database import salient_frame_selector
from driftmap.core.topomap.model import NodeFrames
from driftmap.errors import BadInputError

SEED = 7
ENTROPY_TOL_BITS = 0.1  # a 64x64 uniform patch falls this short of log2(256) at most
SAD_TOL = 1e-6
NOISE_SALIENCY_MAX = 0.05  # SS / SS_m left on a flat frame with 1 grey level of noise


def _textured_patch_image(rng: np.random.Generator) -> np.ndarray:
    img = np.full((76, 160), 90, dtype=np.uint8)
    img[20:40, 60:80] = rng.integers(0, 256, (20, 20), dtype=np.uint8)
    return img


class TestPatchEntropy:
    def test_constant_patch_is_zero(self) -> None:
        ent = patch_entropy(np.full((20, 20), 123, dtype=np.uint8), 10)
        assert ent.shape == (2, 2)
        assert np.all(ent == 0.0)

    def test_uniform_random_patch_near_log2_bins(self) -> None:
        img = np.random.default_rng(SEED).integers(0, 256, (64, 64), dtype=np.uint8)
        ent = patch_entropy(img, 64, bins=256)
        assert ent.shape == (1, 1)
        assert math.log2(256) - ENTROPY_TOL_BITS < ent[0, 0] <= math.log2(256)

    def test_two_levels_one_bit_and_border_patches(self) -> None:
        img = np.zeros((7, 12), dtype=np.uint8)
        img[:, 1::2] = 200  # every patch holds two intensities in equal shares (5 px wide: 2 vs 3)
        ent = patch_entropy(img, 4)
        assert ent.shape == (2, 3)  # 7x12 -> border patches kept, smaller
        assert np.allclose(ent, 1.0)

    def test_stack_matches_single(self) -> None:
        rng = np.random.default_rng(SEED)
        stack = rng.integers(0, 256, (3, 30, 40), dtype=np.uint8)
        assert np.allclose(patch_entropy(stack, 5)[1], patch_entropy(stack[1], 5))

    def test_matches_naive_histogram(self) -> None:
        rng = np.random.default_rng(SEED)
        img = (rng.integers(0, 256, (23, 31)) // rng.integers(1, 64, (23, 31))).astype(np.uint8)
        for size, bins in ((5, 256), (7, 16), (10, 2)):
            ent = patch_entropy(img, size, bins)
            for ty in range(ent.shape[0]):
                for tx in range(ent.shape[1]):
                    patch = img[ty * size : (ty + 1) * size, tx * size : (tx + 1) * size].astype(int)
                    p = np.bincount((patch * bins // 256).ravel(), minlength=bins) / patch.size
                    p = p[p > 0]
                    assert ent[ty, tx] == pytest.approx(-(p * np.log2(p)).sum(), abs=1e-9)

    def test_rejects_float(self) -> None:
        with pytest.raises(BadInputError):
            patch_entropy(np.zeros((10, 10), dtype=np.float32), 5)


class TestEntropyMask:
    def test_only_the_textured_patch_is_salient(self) -> None:
        img = _textured_patch_image(np.random.default_rng(SEED))
        for size in (5, 10, 20):
            mask = entropy_mask(img, size, SESAME_PAPER)
            expected = np.zeros_like(mask)
            expected[20:40, 60:80] = True
            assert np.array_equal(mask, expected), size

    def test_flat_image_has_no_salient_pixel(self) -> None:
        assert not entropy_mask(np.full((76, 160), 40, dtype=np.uint8), 5, SESAME_PAPER).any()

    def test_min_entropy_floor_removes_noise(self) -> None:
        rng = np.random.default_rng(SEED)
        img = (100 + rng.integers(0, 2, (40, 40))).astype(np.uint8)  # <= 1 bit of sensor noise
        assert entropy_mask(img, 10, SesameParams(min_entropy_bits=0.0, r_threshold=0.0)).any()
        assert not entropy_mask(img, 10, SesameParams(min_entropy_bits=1.0, r_threshold=0.0)).any()

    def test_relative_threshold_between_min_and_max(self) -> None:
        img = np.zeros((10, 30), dtype=np.uint8)
        img[:, 10:20:2] = 255  # middle patch: 1 bit
        img[:, 20:30] = np.arange(100, dtype=np.uint8).reshape(10, 10)  # right patch: log2(100) bits
        mask = entropy_mask(img, 10, SesameParams(r_threshold=0.1))
        assert mask[:, 10:].all() and not mask[:, :10].any()
        mask = entropy_mask(img, 10, SesameParams(r_threshold=0.5))
        assert mask[:, 20:].all() and not mask[:, :20].any()

    def test_default_floor_drops_noisy_flat_frame(self) -> None:
        rng = np.random.default_rng(SEED)
        noisy = np.clip(30 + rng.normal(0, 1, (2, 120, 160)), 0, 255).astype(np.uint8)
        paper, _ = frame_saliency(noisy, SESAME_PAPER)
        default, masks = frame_saliency(noisy, SESAME_DEFAULT)
        assert paper.min() > 0.3  # the relative threshold alone keeps part of the noise
        assert default.max() < NOISE_SALIENCY_MAX < SESAME_DEFAULT.saliency_min
        assert masks.mean() < NOISE_SALIENCY_MAX


class TestHierarchy:
    def test_pixel_dropped_only_when_plain_at_every_scale(self) -> None:
        m5 = np.array([[1, 0, 0, 0]], dtype=bool)
        m10 = np.array([[0, 1, 0, 0]], dtype=bool)
        m20 = np.array([[0, 0, 1, 0]], dtype=bool)
        out = combine_masks(np.stack([m5, m10, m20]))
        assert out.tolist() == [[True, True, True, False]]

    def test_sesame_masks_resize_nearest_to_thumbnail(self) -> None:
        img = _textured_patch_image(np.random.default_rng(SEED))
        masks = sesame_masks(img, SESAME_PAPER, ImageParams(size_px=(64, 32)))
        assert masks.shape == (32, 64) and masks.dtype == np.bool_
        full = sesame_masks(img, SESAME_PAPER)
        assert full.shape == (76, 160)
        assert np.array_equal(full[20:40, 60:80], np.ones((20, 20), dtype=bool))
        assert masks[12, 28] and not masks[2, 2]

    def test_frame_saliency_fraction_and_thumbnail(self) -> None:
        img = _textured_patch_image(np.random.default_rng(SEED))
        sal, masks = frame_saliency(np.stack([img, img]), SESAME_PAPER, ImageParams(size_px=(64, 32)))
        assert sal.shape == (2,) and masks.shape == (2, 32, 64)
        assert sal[0] == pytest.approx(20 * 20 / (160 * 76))
        assert np.array_equal(masks[0], sesame_masks(img, SESAME_PAPER, ImageParams(size_px=(64, 32))))

    def test_switches(self) -> None:
        img = _textured_patch_image(np.random.default_rng(SEED))
        assert sesame_masks(img, SesameParams(use_mask=False)).all()
        single = sesame_masks(img, SesameParams(use_hierarchy=False, patch_sizes_px=(5, 20)))
        assert np.array_equal(single, entropy_mask(img, 5, SESAME_PAPER))


class TestMaskedSad:
    def test_non_salient_differences_are_ignored(self) -> None:
        rng = np.random.default_rng(SEED)
        query = rng.normal(size=(32, 64)).astype(np.float32)
        mask = np.zeros((32, 64), dtype=bool)
        mask[8:24, 16:48] = True
        ref = query.copy()
        ref_changed = ref.copy()
        ref_changed[~mask] = rng.normal(size=int((~mask).sum())) * 5
        params = SadParams(max_shift_x_px=0, max_shift_y_px=0)
        d = masked_sad(query, np.stack([ref, ref_changed]), mask, params)
        assert abs(float(d[0]) - float(d[1])) < SAD_TOL
        plain = masked_sad(query, np.stack([ref, ref_changed]), None, params)
        assert plain[1] > plain[0] + 0.5


class TestSaliencyScore:
    def test_eq8_eq9_on_hand_values(self) -> None:
        mask = np.zeros((76, 160), dtype=bool)
        mask[:38] = True  # half the pixels salient
        ss = saliency_score(mask)
        assert ss == 255.0 * 38 * 160
        assert saliency_score_max((160, 76)) == 255.0 * 160 * 76
        assert ss / saliency_score_max((160, 76)) == pytest.approx(0.5)
        assert saliency_score(np.stack([mask, ~mask, np.zeros_like(mask)])).tolist() == [
            ss,
            ss,
            0.0,
        ]


def _node_thumbs() -> np.ndarray:
    rng = np.random.default_rng(SEED)
    view_a = rng.normal(size=(32, 64)).astype(np.float32)
    view_b = rng.normal(size=(32, 64)).astype(np.float32)
    noise = rng.normal(scale=0.01, size=(5, 32, 64)).astype(np.float32)
    return np.stack([view_a, view_a, view_b, view_a, view_b]) + noise


class TestBuildSalientDatabase:
    xy = np.array([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0], [0.3, 0.0], [5.0, 0.0]])
    sal = np.array([0.6, 0.9, 0.7, 0.8, 0.4])

    def test_algorithm_1(self) -> None:
        # 0: new view, kept; 1: same view as 0 and more salient, replaces it; 2: other view, kept;
        # 3: same view as 1 but less salient, dropped; 4: far away but below S_th, dropped.
        kept = build_salient_database(self.xy, self.sal, _node_thumbs(), None, SESAME_PAPER)
        assert kept.tolist() == [1, 2]

    def test_far_frame_of_same_view_is_new_place(self) -> None:
        sal = self.sal.copy()
        sal[4] = 0.55
        kept = build_salient_database(self.xy, sal, _node_thumbs(), None, SESAME_PAPER)
        assert kept.tolist() == [1, 2, 4]

    def test_selector_fits_topomap_hook(self) -> None:
        thumbs = _node_thumbs()
        chain_ptr = np.array([0, 3, 5], dtype=np.int64)
        good = np.array([True, True, True, True, False])
        select = salient_frame_selector(self.sal, thumbs, chain_ptr, None, good, SESAME_PAPER)
        chain = np.array([1, 0, 0, 0, 1], dtype=np.int64)  # node rows in arbitrary order
        row = np.array([0, 0, 1, 2, 1], dtype=np.int64)  # flat frames 3, 0, 1, 2, 4
        cands = NodeFrames(
            node=0,
            centre_m=np.zeros(2),
            chain=chain,
            row=row,
            frame_id=np.arange(5, dtype=np.int64),
            xy_m=self.xy[chain_ptr[chain] + row],
            yaw_rad=np.zeros(5),
            dist_m=np.zeros(5),
            quality=np.zeros(5),
            visit=np.zeros(5, dtype=np.int64),
        )
        (pick,) = select([cands], 3)
        assert pick.dtype == np.int64
        assert (chain_ptr[chain] + row)[pick].tolist() == [1, 2]  # most salient first
        assert (chain_ptr[chain] + row)[select([cands], 1)[0]].tolist() == [1]

    def test_masks_used_when_enabled(self) -> None:
        thumbs = patch_normalise(_node_thumbs(), 5)
        masks = np.ones(thumbs.shape, dtype=bool)
        kept = build_salient_database(self.xy, self.sal, thumbs, masks, SESAME_DEFAULT)
        assert kept.tolist() == [1, 2]

    @staticmethod
    def _crowded_nodes() -> tuple[list[np.ndarray], np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Groups of frames of six views, most within A_th of each other: (groups, xy, sal, thumbs, masks)."""
        rng = np.random.default_rng(SEED + 1)
        views = rng.normal(size=(6, 32, 64)).astype(np.float32)
        n = 300
        thumbs = views[rng.integers(0, 6, n)] + rng.normal(scale=0.05, size=(n, 32, 64)).astype(np.float32)
        masks = rng.random((n, 32, 64)) > 0.3
        masks[::17] = False  # frames without a salient pixel: their comparisons score inf
        sal = rng.uniform(0.3, 1.0, n)
        xy = rng.uniform(0.0, 1.5, (n, 2))  # crowded: most frames have kept frames within A_th
        groups = [rng.choice(n, size, replace=False) for size in (0, 1, 40, 7, 90, 25)]
        return groups, xy, sal, thumbs, masks

    def test_groups_in_lockstep_equal_algorithm_1_on_each(self) -> None:
        """Many nodes at once give what the paper's loop gives on each node alone (a sequential oracle)."""
        groups, xy, sal, thumbs, masks = self._crowded_nodes()
        params = replace(SESAME_DEFAULT, similarity=0.5)
        got = build_salient_databases(groups, [xy[g] for g in groups], sal, thumbs, masks, params)

        def oracle(g: np.ndarray) -> list[int]:
            unique: list[int] = []
            for i in range(g.size):
                near = [u for u in unique if np.hypot(*(xy[g[i]] - xy[g[u]])) < params.adjacency_m]
                d = masked_sad(thumbs[g[i]], thumbs[g[near]], masks[g[i]]) if near else []
                same = next((u for u, dist in zip(near, d, strict=True) if dist < params.similarity), None)
                if same is None and sal[g[i]] > params.saliency_min:
                    unique.append(i)
                elif same is not None and sal[g[i]] > sal[g[same]]:
                    unique[unique.index(same)] = i
            return unique

        assert [k.tolist() for k in got] == [oracle(g) for g in groups]
        assert sum(k.size for k in got) < sum(g.size for g in groups) // 2  # the views were merged

    def test_known_pair_scores_are_used_and_recorded(self) -> None:
        """A second run handed the first run's pairs scores none again and decides alike; known scores are
        what it decides on (made inf, the first run's merges do not happen)."""
        groups, xy, sal, thumbs, masks = self._crowded_nodes()
        params = replace(SESAME_DEFAULT, similarity=0.5)
        args = (groups, [xy[g] for g in groups], sal, thumbs, masks, params)
        first = PairScores()
        plain = build_salient_databases(*args)
        got = build_salient_databases(*args, scores=first)
        assert [k.tolist() for k in got] == [k.tolist() for k in plain]
        assert first.scored > 100  # (a few pairs recur: the groups share frames)
        q, r, d = first.arrays()
        assert q.size == first.scored and np.isinf(d).any()  # the masks without a salient pixel
        np.testing.assert_array_equal(d, sad_pairs(thumbs, q, r, masks=masks).d)
        second = PairScores(q, r, d)
        again = build_salient_databases(*args, scores=second)
        assert [k.tolist() for k in again] == [k.tolist() for k in plain]
        assert (second.reused, second.scored) == (first.reused + first.scored, 0)
        assert all(a.size == b.size for a, b in zip(second.arrays(), first.arrays(), strict=True))
        unlike = PairScores(q, r, np.full(q.size, np.inf, dtype=np.float32))
        apart = build_salient_databases(*args, scores=unlike)
        assert sum(k.size for k in apart) > sum(k.size for k in plain)

    def test_pair_scores_reject_ragged_arrays(self) -> None:
        with pytest.raises(BadInputError, match="query, ref, d"):
            PairScores(np.arange(3), np.arange(2), np.zeros(3, dtype=np.float32))


class TestParams:
    def test_paper_defaults(self) -> None:
        assert SESAME_PAPER.mask_size_px == (160, 76)
        assert SESAME_PAPER.patch_sizes_px == (5, 10, 20)
        assert (SESAME_PAPER.adjacency_m, SESAME_PAPER.similarity, SESAME_PAPER.saliency_min) == (
            0.5,
            0.25,
            0.5,
        )

    def test_rejects_bad_threshold(self) -> None:
        with pytest.raises(BadInputError):
            SesameParams(r_threshold=1.5)


class TestTopomapIntegration:
    def test_build_topomap_with_salient_selector(self) -> None:
        rng = np.random.default_rng(SEED)
        x = np.arange(0.0, 20.0, 0.25)
        n = x.size
        pose = np.stack([x, np.zeros(n), np.zeros(n)], axis=1)
        views = rng.normal(size=(n, 32, 64)).astype(np.float32)  # one view per position
        thumbs = np.concatenate([views, views + 0.01])  # the second drive sees the same views
        sal = rng.uniform(0.3, 1.0, 2 * n)
        chain_ptr = np.array([0, n, 2 * n], dtype=np.int64)
        select = salient_frame_selector(sal, thumbs, chain_ptr, params=SESAME_PAPER)
        topo = build_topomap([pose, pose.copy()], select_frames=select)
        assert topo.chosen.size >= topo.n_nodes
        for node in range(topo.n_nodes):
            chosen = topo.chosen[topo.chosen_ptr[node] : topo.chosen_ptr[node + 1]]  # flat frames
            assert chosen.size <= topo.params.frames_per_node
            assert np.all(sal[chosen] > SESAME_PAPER.saliency_min)
            position = chosen % n
            assert np.unique(position).size == position.size  # one frame per unique view
            for flat in chosen:  # of the two drives' frames of a view, the more salient is kept
                assert sal[flat] >= sal[(flat + n) % (2 * n)]
