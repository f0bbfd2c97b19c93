"""Tests of driftmap.core.imaging.sad: shifted, overlap-normalised, masked SAD and shift registration."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from driftmap.core.imaging.images import mask_pyramid, patch_normalise, pyramid
from driftmap.core.imaging.params import SadParams
from driftmap.core.imaging.registration import register_shift
from driftmap.core.imaging.sad import sad_matrix, sad_one_to_many, sad_pairs
from driftmap.core.imaging.shift_cost import TwoSidedCost

SEED = 3
FLOAT_TOL = 1e-4  # float32 vectorised sums against float64 loops
SUBPIXEL_TOL = 0.05  # pixels, Gauss-Newton sub-pixel shift on smooth random texture
H, W = 24, 40


def texture(shape: tuple[int, int], seed: int = SEED) -> np.ndarray:
    noise = np.random.default_rng(seed).standard_normal(shape).astype(np.float32)
    return np.asarray(cv2.GaussianBlur(noise, (0, 0), 1.2), dtype=np.float32)


def shifted_views(dxs_dys: list[tuple[int, int]]) -> tuple[np.ndarray, np.ndarray]:
    """A query crop of a big texture and references whose content moved by (dx, dy)."""
    big = patch_normalise(texture((H + 20, W + 20)), 6)
    query = big[10 : 10 + H, 10 : 10 + W]
    refs = np.stack([big[10 - dy : 10 - dy + H, 10 - dx : 10 - dx + W] for dx, dy in dxs_dys])
    return query, refs


def naive_masked(
    query: np.ndarray, ref: np.ndarray, max_dx: int, max_dy: int, mask: np.ndarray | None
) -> float:
    """Paper 001 eq. 6 written out: min over shifts of sum(M |q - r|) / sum(M) over the overlap."""
    m = np.ones_like(query) if mask is None else mask
    best = np.inf
    for dy in range(-max_dy, max_dy + 1):
        for dx in range(-max_dx, max_dx + 1):
            num = den = 0.0
            for y in range(H):
                for x in range(W):
                    if 0 <= y + dy < H and 0 <= x + dx < W:
                        num += m[y, x] * abs(float(query[y, x]) - float(ref[y + dy, x + dx]))
                        den += m[y, x]
            if den > 0:
                best = min(best, num / den)
    return best


class TestKnownShift:
    @pytest.mark.parametrize("shift", [(0, 0), (3, 1), (-4, 2), (2, -2)])
    def test_minimum_at_the_shift_with_zero_score(self, shift: tuple[int, int]) -> None:
        query, refs = shifted_views([shift, (0, 0)])
        res = sad_one_to_many(query, refs, SadParams(max_shift_x_px=4, max_shift_y_px=2))
        assert tuple(res.shift_px[0]) == shift
        assert res.d[0] < FLOAT_TOL

    def test_overlap_normalisation(self) -> None:
        # Constant images differ by 1 everywhere: the mean over any overlap is exactly 1, whereas a sum
        # divided by the full W x H would favour the largest shift (smallest overlap).
        res = sad_one_to_many(
            np.ones((H, W)), np.full((1, H, W), 2.0), SadParams(max_shift_x_px=4, max_shift_y_px=2)
        )
        assert res.d[0] == pytest.approx(1.0, abs=FLOAT_TOL)

    def test_shift_out_of_range_is_not_found(self) -> None:
        query, refs = shifted_views([(6, 0)])
        res = sad_one_to_many(query, refs, SadParams(max_shift_x_px=4, max_shift_y_px=2))
        assert res.d[0] > 0.1


class TestAgainstNaive:
    def test_one_to_many_and_matrix(self) -> None:
        rng = np.random.default_rng(SEED)
        queries = rng.standard_normal((3, H, W)).astype(np.float32)
        refs = rng.standard_normal((7, H, W)).astype(np.float32)
        params = SadParams(max_shift_x_px=2, max_shift_y_px=1, chunk_bytes=2 * H * W * 4)  # 2 refs per chunk
        expected = np.array([[naive_masked(q, r, 2, 1, None) for r in refs] for q in queries])
        assert np.allclose(sad_matrix(queries, refs, params), expected, atol=FLOAT_TOL)
        assert np.allclose(sad_one_to_many(queries[1], refs, params).d, expected[1], atol=FLOAT_TOL)

    def test_masked_matches_manual(self) -> None:
        rng = np.random.default_rng(SEED + 1)
        queries = rng.standard_normal((2, H, W)).astype(np.float32)
        refs = rng.standard_normal((5, H, W)).astype(np.float32)
        masks = (rng.random((2, H, W)) > 0.6).astype(np.float32)
        params = SadParams(max_shift_x_px=2, max_shift_y_px=1, chunk_bytes=3 * H * W * 4)
        expected = np.array(
            [[naive_masked(q, r, 2, 1, m) for r in refs] for q, m in zip(queries, masks, strict=True)]
        )
        assert np.allclose(sad_matrix(queries, refs, params, masks), expected, atol=FLOAT_TOL)
        one = sad_one_to_many(queries[0], refs, params, masks[0]).d
        assert np.allclose(one, expected[0], atol=FLOAT_TOL)

    def test_empty_mask_scores_inf(self) -> None:
        query, refs = shifted_views([(0, 0)])
        res = sad_one_to_many(query, refs, SadParams(), np.zeros((H, W), np.float32))
        assert np.isinf(res.d[0])


class TestPairs:
    def test_pairs_agree_with_one_to_many(self) -> None:
        rng = np.random.default_rng(2)
        frames = patch_normalise(rng.integers(0, 255, (40, H, W)).astype(np.uint8))
        qi, rj = rng.integers(0, 40, 300), rng.integers(0, 40, 300)
        params = SadParams(max_shift_x_px=3, max_shift_y_px=2, chunk_bytes=64 * 1024)
        got = sad_pairs(frames, qi, rj, params)
        for p in range(0, 300, 7):
            ref = sad_one_to_many(frames[qi[p]], frames[rj[p]][None], params)
            assert got.d[p] == pytest.approx(ref.d[0], abs=FLOAT_TOL)
            assert tuple(got.shift_px[p]) == tuple(ref.shift_px[0])

    def test_masked_pairs_match_manual(self) -> None:
        """Eq. 6 with each query's own mask; a query whose mask misses every overlap scores inf."""
        rng = np.random.default_rng(SEED + 2)
        frames = rng.standard_normal((6, H, W)).astype(np.float32)
        masks = rng.random((6, H, W)) > 0.6
        masks[4] = False
        masks[5] = False
        masks[5, 0, :] = True  # only the top row: gone at every downward shift, kept at dy <= 0
        qi, rj = np.array([0, 1, 2, 4, 5, 3, 0]), np.array([1, 2, 3, 0, 1, 0, 0])
        params = SadParams(max_shift_x_px=2, max_shift_y_px=1, chunk_bytes=3 * H * W * 4)  # 3 pairs per chunk
        got = sad_pairs(frames, qi, rj, params, masks)
        expected = [
            naive_masked(frames[q], frames[r], 2, 1, masks[q].astype(np.float32))
            for q, r in zip(qi, rj, strict=True)
        ]
        assert np.isinf(got.d[3]) and np.isinf(expected[3])
        finite = np.isfinite(expected)
        assert np.allclose(got.d[finite], np.asarray(expected)[finite], atol=FLOAT_TOL)
        alone = [sad_pairs(frames, qi[p : p + 1], rj[p : p + 1], params, masks).d[0] for p in range(qi.size)]
        assert np.array_equal(got.d, np.asarray(alone, dtype=np.float32))  # the same whatever the batch

    def test_bad_pairs(self) -> None:
        frames = np.zeros((3, H, W), np.float32)
        with pytest.raises(ValueError, match="indices"):
            sad_pairs(frames, np.array([0]), np.array([3]))
        with pytest.raises(ValueError, match="masks"):
            sad_pairs(frames, np.array([0]), np.array([1]), masks=np.ones((3, H, W + 1), bool))


class TestShapes:
    def test_mismatched_refs(self) -> None:
        with pytest.raises(ValueError):
            sad_one_to_many(np.zeros((H, W)), np.zeros((3, H, W + 1)))

    def test_range_leaves_no_overlap(self) -> None:
        with pytest.raises(ValueError):
            sad_one_to_many(np.zeros((4, 4)), np.zeros((1, 4, 4)), SadParams(max_shift_x_px=4))

    def test_bad_mask(self) -> None:
        with pytest.raises(ValueError):
            sad_one_to_many(np.zeros((H, W)), np.zeros((1, H, W)), SadParams(), np.zeros((H, W + 1)))


class TestRegisterShift:
    @staticmethod
    def pair(shift: tuple[float, float], size: int = 160) -> tuple[np.ndarray, np.ndarray]:
        img = texture((size, size)) * 40 + 128
        move = np.array(
            [[1, 0, shift[0]], [0, 1, shift[1]]], dtype=np.float32
        )  # content of a moves by shift in b
        moved = cv2.warpAffine(img, move, (size, size), flags=cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
        return img, moved

    @pytest.mark.parametrize("shift", [(0.0, 0.0), (5.3, -2.7), (-17.6, 11.2)])
    def test_recovers_subpixel_shift(self, shift: tuple[float, float]) -> None:
        a, b = self.pair(shift)
        roi = np.zeros(a.shape, np.float32)
        roi[40:120, 40:120] = 1.0
        valid = np.ones_like(roi)
        levels = 2
        norm = (
            [patch_normalise(p, 6) for p in pyramid(a, levels)],
            [patch_normalise(p, 6) for p in pyramid(b, levels)],
        )
        match = register_shift(
            *norm, mask_pyramid(roi, levels), mask_pyramid(valid, levels), 24, 24, subpixel="lk"
        )
        assert match.shift_px[0] == pytest.approx(shift[0], abs=SUBPIXEL_TOL)
        assert match.shift_px[1] == pytest.approx(shift[1], abs=SUBPIXEL_TOL)
        assert not match.at_range_edge and match.distinctiveness > 0.3

    def test_roi_at_the_border_is_matched_two_sided(self) -> None:
        a, b = self.pair((0.0, 9.0))  # content moves down and out of the frame's lower edge
        roi = np.zeros(a.shape, np.float32)
        roi[130:160, 30:130] = 1.0  # ROI touching the bottom: only b's ROI finds its partner in a
        valid = np.ones_like(roi)
        match = register_shift(
            [patch_normalise(a, 6)], [patch_normalise(b, 6)], [roi], [valid], 12, 12, subpixel="lk"
        )
        assert match.shift_px[1] == pytest.approx(9.0, abs=SUBPIXEL_TOL)

    def test_an_extra_start_is_one_more_descent(self) -> None:
        """``also_from_px`` gives what the exhaustive run and a descent from that start give, whichever
        ends lower, with the exhaustive run's distinctiveness (one cost table, one sub-pixel refinement)."""
        a, b = self.pair((22.4, -2.7))  # beyond the exhaustive range below: only a start can get there
        roi = np.zeros(a.shape, np.float32)
        roi[40:120, 40:120] = 1.0
        levels = 2
        args = (
            [patch_normalise(p, 6) for p in pyramid(a, levels)],
            [patch_normalise(p, 6) for p in pyramid(b, levels)],
            mask_pyramid(roi, levels),
            mask_pyramid(np.ones_like(roi), levels),
            12,
            12,
        )
        exhaustive = register_shift(*args, candidates=1, subpixel="lk")
        won = []
        for start in [(5, -1), (1, 1), (-2, 0)]:  # coarsest-level pixels (a quarter of level 0)
            alone = register_shift(*args, start_px=start, subpixel="lk")
            both = register_shift(*args, candidates=1, also_from_px=start, subpixel="lk")
            best = min(exhaustive, alone, key=lambda m: m.cost)
            assert both.shift_px == best.shift_px and both.cost == best.cost
            assert both.distinctiveness == exhaustive.distinctiveness
            won.append(alone.cost < exhaustive.cost)
        assert won == [True, False, False]
        assert register_shift(*args, candidates=1, also_from_px=(5, -1), subpixel="lk").shift_px == (
            pytest.approx((22.4, -2.7), abs=SUBPIXEL_TOL)
        )

    def test_cost_counts_only_valid_partners(self) -> None:
        """The two-sided cost of a shift, written out, with partners missing in part of each image (the
        shortcut for shifts whose partners are all valid must agree with the weighted sum)."""
        a, b = (patch_normalise(x, 6) for x in self.pair((3.0, -2.0), size=64))
        roi = np.zeros(a.shape, np.float32)
        roi[16:48, 12:50] = 1.0
        valid = np.ones_like(roi)
        valid[:, 54:] = 0.0  # the right edge of both frames shows nothing
        cost = TwoSidedCost(a, b, roi, valid, roi, valid)
        for dx, dy in [(0, 0), (3, -2), (-4, 5), (6, 1)]:  # (6, 1): a's ROI reaches the invalid columns
            num = den = 0.0
            for src, dst, sign in ((a, b, 1), (b, a, -1)):
                moved_valid = np.roll(valid, (-sign * dy, -sign * dx), axis=(0, 1))
                moved = np.roll(dst, (-sign * dy, -sign * dx), axis=(0, 1))
                w = roi * moved_valid
                num += float(np.sum(w * np.abs(src - moved), dtype=np.float64))
                den += float(w.sum())
            for _ in range(2):  # computed, then remembered
                got = cost(dx, dy)
                assert got[1] == pytest.approx(den)
                assert got[0] == pytest.approx(num / den, rel=1e-5)
