"""Loop closure by shifted SAD with coarse candidates and sequence checks ([SSLAM] III-A-2, eq. 3).

The synthetic world is a long strip of blurred random texture (a tunnel wall seen side-on); a
keyframe is a 64x32 view of it, one every 32 pixels, with pixel jitter and noise, patch normalised.
A second pass over the same stretch revisits it; short pieces of the stretch pasted elsewhere are
aliases: places that look alike for a frame or two but are not the same.
"""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.core.imaging.images import patch_normalise
from driftmap.core.loop_closure.descriptors import _sequence_filter
from driftmap.core.loop_closure.params import LOOPS_DEFAULT, LOOPS_PAPER, LoopParams
from driftmap.core.loop_closure.search import LoopResult, detect_loops

H, W, STEP_PX, MARGIN_PX = 32, 64, 32, 8
N_REGION_A = 150  # views of the stretch both passes cover
N_REGION_B = 60  # views only the second pass sees; it holds the aliases
N_ALIASES = 8  # pieces of region A pasted into region B
RECALL_MIN = 0.8  # revisiting keyframes that must get a closure ...
INDEX_TOL = 2  # ... within this many keyframes of the true one
FULL_FRACTION_MAX = 0.05  # full SAD comparisons / (N^2 / 2) at N = 2,000
SAD_TOL = 1e-5  # sad_pairs vs sad_one_to_many

F32 = NDArray[np.float32]


def make_strip(n_views: int, rng: np.random.Generator) -> F32:
    noise = rng.normal(0.0, 1.0, (H + 8, n_views * STEP_PX + W + 2 * MARGIN_PX)).astype(np.float32)
    return np.asarray(cv2.GaussianBlur(noise, (0, 0), 1.2), dtype=np.float32)


def views(
    strip: F32, where: NDArray[np.int64], rng: np.random.Generator, *, phase_px: int = 0, jitter_px: int = 2
) -> F32:
    """Patch-normalised views at strip positions ``where`` (in views), jittered and noisy."""
    xs = where * STEP_PX + MARGIN_PX + phase_px + rng.integers(-jitter_px, jitter_px + 1, where.size)
    ys = 4 + rng.integers(-1, 2, where.size)
    out = np.stack([strip[y : y + H, x : x + W] for x, y in zip(xs, ys, strict=True)])
    out += rng.normal(0.0, 0.08, out.shape).astype(np.float32)
    return patch_normalise(out, 8)


def paste(strip: F32, src_view: int, dst_view: int, width_px: int) -> None:
    a, b = src_view * STEP_PX + MARGIN_PX, dst_view * STEP_PX + MARGIN_PX
    strip[:, b : b + width_px] = strip[:, a : a + width_px]


@pytest.fixture(scope="module")
def aliased_world() -> tuple[list[F32], NDArray[np.int64]]:
    """Pass 1 over region A; pass 2 over A, then into region B where pieces of A reappear.

    Returns the two chains and, per pass-2 keyframe, the pass-1 keyframe of the same place (-1 in B).
    """
    rng = np.random.default_rng(7)
    strip = make_strip(N_REGION_A + N_REGION_B + 2, rng)
    sources = rng.choice(np.arange(10, N_REGION_A - 10), N_ALIASES, replace=False)
    for k, src in enumerate(sources):
        paste(strip, int(src), N_REGION_A + 4 + 7 * k, W)  # one identical view, two half-overlapping
    pass1 = views(strip, np.arange(N_REGION_A), rng)
    pass2 = views(strip, np.arange(N_REGION_A + N_REGION_B), rng, phase_px=1)
    truth = np.where(np.arange(N_REGION_A + N_REGION_B) < N_REGION_A, np.arange(N_REGION_A + N_REGION_B), -1)
    return [pass1, pass2], truth


def cross_closures(result: LoopResult) -> NDArray[np.int64]:
    """``(K, 2)`` (pass-2 index, pass-1 index) of the closures from chain 1 to chain 0."""
    pairs = result.pairs()
    return np.asarray(pairs[(pairs[:, 0] == 1) & (pairs[:, 2] == 0)][:, [1, 3]], dtype=np.int64)


def wrong_closures(result: LoopResult, truth: NDArray[np.int64]) -> int:
    """Closures between different places: chain 1 -> 0 off the truth, or any within chain 0."""
    cross = cross_closures(result)
    off = (truth[cross[:, 0]] < 0) | (np.abs(cross[:, 1] - truth[cross[:, 0]]) > INDEX_TOL)
    pairs = result.pairs()
    return int(off.sum()) + int(np.sum(pairs[:, 0] == pairs[:, 2]))


class TestRevisits:
    def test_most_revisiting_keyframes_get_a_closure_near_the_truth(
        self, aliased_world: tuple[list[F32], NDArray[np.int64]]
    ) -> None:
        chains, truth = aliased_world
        result = detect_loops(chains)
        cross = cross_closures(result)
        good = (truth[cross[:, 0]] >= 0) & (np.abs(cross[:, 1] - truth[cross[:, 0]]) <= INDEX_TOL)
        recallable = np.arange(LOOPS_DEFAULT.seq_len - 1, N_REGION_A)
        recall = np.isin(recallable, cross[good, 0]).mean()
        assert recall >= RECALL_MIN

    def test_closure_fields(self, aliased_world: tuple[list[F32], NDArray[np.int64]]) -> None:
        chains, _ = aliased_world
        result = detect_loops(chains)
        assert result.closures
        for c in result.closures:
            assert c.seq_d < result.stats.d_t
            assert 0.0 <= c.confidence <= 1.0
            assert LOOPS_DEFAULT.sigma_xy_m <= c.sigma_xy_m <= LOOPS_DEFAULT.sigma_xy_max_m
            assert abs(c.shift_px[0]) <= LOOPS_DEFAULT.sad.max_shift_x_px
        assert result.stats.d_t < result.stats.d_hit < result.stats.background_median

    def test_shift_is_the_view_offset(self) -> None:
        rng = np.random.default_rng(3)
        strip = make_strip(80, rng)
        where = np.arange(80)
        chains = [views(strip, where, rng, jitter_px=0), views(strip, where, rng, phase_px=3, jitter_px=0)]
        dx = [c.shift_px[0] for c in detect_loops(chains).closures if c.idx_a == c.idx_b]
        assert dx
        assert np.median(dx) == 3  # query pixel x shows what reference pixel x + 3 shows

    def test_reverse_travel_closes_only_with_negative_slopes(self) -> None:
        rng = np.random.default_rng(4)
        strip = make_strip(100, rng)
        chains = [views(strip, np.arange(100), rng), views(strip, np.arange(100)[::-1], rng)]
        backwards = cross_closures(detect_loops(chains))
        assert len(backwards) >= RECALL_MIN * 90
        assert np.all(np.abs(99 - backwards[:, 0] - backwards[:, 1]) <= INDEX_TOL)
        forward_only = dataclasses.replace(LOOPS_DEFAULT, seq_slopes=(0.67, 1.0, 1.5), track=False)
        assert len(cross_closures(detect_loops(chains, forward_only))) == 0


class TestAliasing:
    def test_sequence_consistency_rejects_aliases_a_single_frame_accepts(
        self, aliased_world: tuple[list[F32], NDArray[np.int64]]
    ) -> None:
        chains, truth = aliased_world
        assert wrong_closures(detect_loops(chains), truth) == 0
        single = detect_loops(chains, LOOPS_PAPER)  # the paper's rule: best frame with d < d_t
        assert wrong_closures(single, truth) > 0

    def test_two_equally_good_places_give_no_closure(self) -> None:
        # Chain 0 saw one stretch twice within its recent window, so nothing links the two passes;
        # chain 1 then matches both equally well and cannot tell which place it is at.
        rng = np.random.default_rng(5)
        strip = make_strip(16, rng)
        where = np.arange(16)
        chains = [
            np.concatenate([views(strip, where, rng), views(strip, where, rng)]),
            views(strip, where, rng),
        ]
        params = dataclasses.replace(LOOPS_DEFAULT, recent_frames=20)
        assert detect_loops(chains, params).closures == []
        blind = dataclasses.replace(params, uniqueness_ratio=1.0, track=False)
        assert len(detect_loops(chains, blind).closures) > 0

    def test_tracking_carries_a_distinctive_entry_through_an_aliased_stretch(self) -> None:
        # Chain 0 drove A then the stretch S twice (copies within its recent window, never linked);
        # chain 1 drives A then S: entering S its sequence still holds A, so the first copy wins;
        # deeper in S both copies tie, and only continuing the previous closure keeps the match.
        rng = np.random.default_rng(9)
        strip = make_strip(26, rng)
        a, s = np.arange(10), np.arange(10, 26)
        chains = [views(strip, np.concatenate([a, s, s]), rng), views(strip, np.concatenate([a, s]), rng)]
        tracked = cross_closures(detect_loops(chains))
        assert np.all(tracked[:, 0] == tracked[:, 1])  # always the first copy, the one after A
        assert np.isin(s, tracked[:, 0]).mean() >= RECALL_MIN
        untracked = cross_closures(detect_loops(chains, dataclasses.replace(LOOPS_DEFAULT, track=False)))
        assert np.isin(s, untracked[:, 0]).mean() < 0.5


class TestRecentWindow:
    @pytest.mark.parametrize("recent_frames", [5, 20])
    def test_recent_frames_are_never_matched(self, recent_frames: int) -> None:
        rng = np.random.default_rng(6)
        strip = make_strip(60, rng)
        slow = np.repeat(np.arange(60), 3)  # three near-identical keyframes per place ...
        loop = np.concatenate([slow, slow])  # ... and the stretch again
        params = dataclasses.replace(LOOPS_DEFAULT, recent_frames=recent_frames)
        pairs = detect_loops([views(strip, loop, rng)], params).pairs()
        assert len(pairs) > 0
        assert np.all(pairs[:, 1] - pairs[:, 3] > recent_frames)

    def test_recent_seconds(self) -> None:
        rng = np.random.default_rng(6)
        strip = make_strip(60, rng)
        slow = np.repeat(np.arange(60), 3)
        chain = views(strip, np.concatenate([slow, slow]), rng)
        t_s = np.arange(chain.shape[0], dtype=np.float64) * 0.5
        no_window = dataclasses.replace(LOOPS_DEFAULT, recent_frames=0)
        pairs = detect_loops([chain], no_window, timestamps_s=[t_s]).pairs()
        assert np.any(t_s[pairs[:, 1]] - t_s[pairs[:, 3]] < 20.0)  # without a window: the same stop
        seconds = dataclasses.replace(no_window, recent_s=20.0)
        pairs = detect_loops([chain], seconds, timestamps_s=[t_s]).pairs()
        assert len(pairs) > 0
        assert np.all(t_s[pairs[:, 1]] - t_s[pairs[:, 3]] >= 20.0)


class TestCost:
    def test_full_comparisons_far_below_all_pairs(self) -> None:
        rng = np.random.default_rng(8)
        strip = make_strip(1000, rng)
        chains = [views(strip, np.arange(1000), rng), views(strip, np.arange(1000), rng, phase_px=1)]
        stats = detect_loops(chains).stats
        n = stats.n_frames
        assert n == 2000
        assert stats.n_full < FULL_FRACTION_MAX * n * (n - 1) / 2
        per_query = LOOPS_DEFAULT.top_k + LOOPS_DEFAULT.top_k_single
        assert stats.n_full_candidates <= per_query * n
        assert set(stats.time_s) == {"descriptors", "coarse", "full", "sequence"}


class TestEdgeCases:
    def test_no_chains(self) -> None:
        assert detect_loops([]).closures == []

    def test_empty_and_single_frames(self) -> None:
        frame = patch_normalise(np.random.default_rng(0).integers(0, 255, (1, H, W)).astype(np.uint8))
        empty = np.zeros((0, H, W), np.float32)
        for chains in ([empty], [frame], [empty, frame], [frame, frame, empty]):
            result = detect_loops(chains)
            assert result.closures == []
            assert result.pairs().shape == (0, 4)

    def test_short_chain_inside_its_window(self) -> None:
        rng = np.random.default_rng(1)
        strip = make_strip(10, rng)
        result = detect_loops([views(strip, np.arange(10), rng)])
        assert result.closures == []
        assert result.stats.n_eligible_pairs == 0


class TestValidation:
    @pytest.mark.parametrize(
        "chains",
        [
            [np.zeros((H, W), np.float32)],  # one frame without the stack axis
            [np.zeros((3, H, W), np.float32), np.zeros((3, H, W + 1), np.float32)],  # two sizes
            [np.zeros((3, 2, H, W), np.float32)],
        ],
    )
    def test_bad_chain_shapes(self, chains: list[F32]) -> None:
        with pytest.raises(ValueError):
            detect_loops(chains)

    @pytest.mark.parametrize(
        "timestamps",
        [[np.zeros(3)], [np.zeros(4), np.zeros(2)], [np.zeros(3), np.array([0.0, 2.0, 1.0])]],
    )
    def test_bad_timestamps(self, timestamps: list[NDArray[np.float64]]) -> None:
        chains = [np.zeros((4, H, W), np.float32), np.zeros((3, H, W), np.float32)]
        with pytest.raises(ValueError):
            detect_loops(chains, timestamps_s=timestamps)

    def test_shift_range_larger_than_frames(self) -> None:
        chains = [np.zeros((30, 4, 4), np.float32)]
        with pytest.raises(ValueError):
            detect_loops(chains, dataclasses.replace(LOOPS_DEFAULT, recent_frames=2))

    @pytest.mark.parametrize(
        "change",
        [
            {"d_t": 0.0},
            {"top_k": 0},
            {"seq_len": 3, "seq_min_hits": 4},
            {"seq_slopes": (0.0, 1.0)},
            {"uniqueness_ratio": 1.5},
            {"recent_frames": -1},
            {"sigma_xy_m": 8.0},
        ],
    )
    def test_bad_params(self, change: dict[str, object]) -> None:
        with pytest.raises(ValueError):
            LoopParams(**change)  # type: ignore[arg-type]


class TestScores:
    def test_sequence_filter_is_the_mean_along_diagonals_within_chains(self) -> None:
        rng = np.random.default_rng(0)
        for _ in range(20):
            seq_len, q0 = int(rng.integers(1, 6)), int(rng.integers(0, 5))
            rows, cols = int(rng.integers(1, 10)), int(rng.integers(1, 14))
            s = rng.normal(size=(q0 + rows, cols)).astype(np.float32)
            q_all = np.zeros(q0 + rows, np.int64)  # chain positions: count up, restart at random
            r_pos = np.zeros(cols, np.int64)
            for k in range(1, q0 + rows):
                q_all[k] = 0 if rng.random() < 0.2 else q_all[k - 1] + 1
            for k in range(1, cols):
                r_pos[k] = 0 if rng.random() < 0.25 else r_pos[k - 1] + 1
            got = _sequence_filter(s, q0, q_all[q0:], r_pos, seq_len, 1)
            wide = cv2.dilate(s, np.ones((1, 3), np.uint8), borderType=cv2.BORDER_REPLICATE)
            for i in range(rows):
                for j in range(cols):
                    terms = [
                        (s if lag == 0 else wide)[q0 + i - lag, j - lag]
                        for lag in range(seq_len)
                        if q_all[q0 + i] >= lag and r_pos[j] >= lag and q0 + i >= lag
                    ]
                    assert got[i, j] == pytest.approx(np.mean(terms), abs=1e-5)
