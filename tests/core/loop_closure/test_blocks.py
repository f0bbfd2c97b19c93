"""The loop-closure search split into query blocks (driftmap.core.loop_closure.blocks) decides like one run.

A map build scores blocks of queries in ``map.loops`` subtasks on any worker and decides at the join;
the closures must be exactly those of :func:`detect_loops` on one machine. The world: three passes over
one stretch of a textured tunnel wall (the strip of test_loops), 900 keyframes, four query blocks.
"""

from __future__ import annotations

import io
from dataclasses import replace

import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.core.imaging.images import patch_normalise
from driftmap.core.imaging.sad import sad_pairs
from driftmap.core.loop_closure.blocks import (
    LoopSearch,
    QueryScores,
    plan_search,
    score_queries,
    split_queries,
)
from driftmap.core.loop_closure.descriptors import coarse_candidates, query_blocks
from driftmap.core.loop_closure.params import LOOPS_DEFAULT, LOOPS_PAPER, LoopParams
from driftmap.core.loop_closure.resume import SearchBasis, resumable_blocks
from driftmap.core.loop_closure.search import decide_loops, detect_loops
from tests.core.loop_closure.test_search import make_strip, views

N_VIEWS = 300
F32 = NDArray[np.float32]


@pytest.fixture(scope="module")
def three_passes() -> list[F32]:
    rng = np.random.default_rng(3)
    strip = make_strip(N_VIEWS + 2, rng)
    return [views(strip, np.arange(N_VIEWS), rng, phase_px=k) for k in range(3)]


def plan(chains: list[F32], params: LoopParams) -> LoopSearch:
    search = plan_search(chains, params)
    assert search is not None
    return search


def npz_round_trip(arrays: dict[str, NDArray]) -> dict[str, NDArray]:
    buffer = io.BytesIO()
    np.savez(buffer, **arrays)  # type: ignore[arg-type]
    with np.load(io.BytesIO(buffer.getvalue())) as loaded:
        return {k: loaded[k] for k in loaded.files}


@pytest.mark.parametrize("params", [LOOPS_DEFAULT, LOOPS_PAPER], ids=["default", "paper"])
def test_blocks_scored_apart_decide_exactly_like_one_run(three_passes: list[F32], params: LoopParams) -> None:
    one_run = detect_loops(three_passes, params)
    search = plan(three_passes, params)
    ranges = split_queries(search, params, 256)
    assert len(ranges) == 4 and ranges[0][0] == 0 and ranges[-1][1] == search.n
    # Each block in its own fresh state, through the bytes a blob store keeps, joined in reverse order.
    shipped = LoopSearch.from_arrays(npz_round_trip(search.to_arrays()))
    blocks = [
        QueryScores.from_arrays(npz_round_trip(score_queries(shipped, params, q0, q1).to_arrays()))
        for q0, q1 in reversed(ranges)
    ]
    split = decide_loops(search, blocks, params)
    assert len(one_run.closures) > 300  # passes 2 and 3 close on the earlier ones
    assert split.closures == one_run.closures
    assert split.stats.d_t == one_run.stats.d_t
    assert split.stats.n_full_candidates == one_run.stats.n_full_candidates
    assert split.stats.n_coarse == one_run.stats.n_coarse


def test_a_search_over_one_more_chain_resumes_the_earlier_one_exactly(three_passes: list[F32]) -> None:
    params = LOOPS_DEFAULT
    earlier = plan(three_passes[:2], params)  # two blocks of two grid blocks each: 0 .. 543 and 543 .. 600
    earlier_blocks = [
        score_queries(earlier, params, q0, q1) for q0, q1 in split_queries(earlier, params, 512)
    ]
    basis = SearchBasis.from_arrays(npz_round_trip(earlier.basis().to_arrays()))
    later = plan_search(three_passes, params, basis=basis)
    assert later is not None and later.n_background == 0  # the thresholds are the earlier search's
    assert np.array_equal(later.desc[: earlier.n], earlier.desc)  # the earlier keyframes' descriptors kept
    grid = query_blocks(later.limit)
    kept = resumable_blocks(later, params, earlier_blocks, earlier.n)
    # The block ending at 600, off the new grid (its last grid block then held 256 queries), is scored again.
    assert kept == earlier_blocks[:1] and kept[0].q1 == max(g for g in grid if g <= earlier.n) < earlier.n
    fresh = [score_queries(later, params, q0, q1) for q0, q1 in split_queries(later, params, 256, kept[0].q1)]
    resumed = decide_loops(later, kept + fresh, params)
    # The same closures as a search over all three chains from scratch in the earlier search's basis.
    scratch = [score_queries(later, params, q0, q1) for q0, q1 in split_queries(later, params, 256)]
    assert resumed.closures == decide_loops(later, scratch, params).closures
    assert len([c for c in resumed.closures if c.chain_a == 2]) > 150  # the third pass closes on the others
    # The second chain changed: the queries up to the last grid point in the first are kept, cut out of the
    # first block, every score as the new search computes it.
    (cut,) = resumable_blocks(later, params, earlier_blocks, N_VIEWS)
    assert cut.q0 == 0 and cut.q1 == max(g for g in grid if g <= N_VIEWS) < earlier_blocks[0].q1
    again = score_queries(later, params, 0, cut.q1).to_arrays()
    for name, array in cut.to_arrays().items():
        if name not in ("counts", "seconds"):
            np.testing.assert_array_equal(array, again[name], err_msg=name)
    same = plan_search(three_passes[:2], params, basis=basis)  # no new keyframe: the earlier descriptors
    assert same is not None and np.array_equal(same.desc, earlier.desc)
    with pytest.raises(ValueError, match="more than the 300 searched"):
        plan_search(three_passes[:1], params, basis=basis)


def test_a_search_planned_afresh_over_more_chains_is_the_resumed_one(three_passes: list[F32]) -> None:
    """With the basis taken from the first chain's keyframes, planning all three chains afresh (a full build)
    gives the basis, descriptors and closures of resuming the search of the first two (an incremental one)."""
    params = replace(LOOPS_DEFAULT, basis_keyframes=N_VIEWS)
    earlier = plan(three_passes[:2], params)
    fresh = plan(three_passes, params)
    assert fresh.n_background > 0 and np.array_equal(fresh.background, earlier.background)
    assert np.array_equal(fresh.mean, earlier.mean) and np.array_equal(fresh.axes, earlier.axes)
    assert np.array_equal(fresh.desc[: earlier.n], earlier.desc)  # each row alike whatever the others
    resumed = plan_search(three_passes, params, basis=earlier.basis())
    assert resumed is not None and np.array_equal(resumed.desc, fresh.desc)
    earlier_blocks = [score_queries(earlier, params, a, b) for a, b in split_queries(earlier, params, 512)]
    kept = resumable_blocks(resumed, params, earlier_blocks, earlier.n)
    rest = split_queries(resumed, params, 256, kept[-1].q1)
    closures = decide_loops(resumed, kept + [score_queries(resumed, params, a, b) for a, b in rest], params)
    assert closures.closures == detect_loops(three_passes, params).closures
    # The default basis (all keyframes here) changes with the chains searched.
    assert not np.array_equal(
        plan(three_passes, LOOPS_DEFAULT).axes, plan(three_passes[:2], LOOPS_DEFAULT).axes
    )


def test_blocks_that_miss_or_repeat_queries_are_refused(three_passes: list[F32]) -> None:
    search = plan(three_passes, LOOPS_DEFAULT)
    (a0, a1), (b0, b1), *_ = split_queries(search, LOOPS_DEFAULT, 256)
    first, second = score_queries(search, LOOPS_DEFAULT, a0, a1), score_queries(search, LOOPS_DEFAULT, b0, b1)
    for blocks in ([first, second], [first, first], [second]):
        with pytest.raises(ValueError, match="do not cover"):
            decide_loops(search, blocks, LOOPS_DEFAULT)


def test_query_ranges_off_the_block_grid_are_refused(three_passes: list[F32]) -> None:
    search = plan(three_passes, LOOPS_DEFAULT)
    grid = query_blocks(search.limit)
    assert grid[0] == LOOPS_DEFAULT.recent_frames + 1 and grid[-1] == search.n
    with pytest.raises(ValueError, match="off the block grid"):
        score_queries(search, LOOPS_DEFAULT, grid[1] + 1, grid[2])
    with pytest.raises(ValueError, match="off the block grid"):
        coarse_candidates(search.desc, search.limit, search.pos, top_k=2, queries=(0, grid[1] - 3))


def test_no_eligible_pair_plans_nothing() -> None:
    rng = np.random.default_rng(0)
    short = patch_normalise(rng.integers(0, 255, (5, 32, 64)).astype(np.uint8))
    assert plan_search([short], LOOPS_DEFAULT) is None
    assert detect_loops([short]).closures == []


def test_a_pairs_score_does_not_depend_on_its_batch() -> None:
    rng = np.random.default_rng(1)
    frames = patch_normalise(rng.integers(0, 255, (300, 32, 64)).astype(np.uint8))
    qi, rj = rng.integers(0, 300, 2000), rng.integers(0, 300, 2000)
    whole = sad_pairs(frames, qi, rj)
    parts = [sad_pairs(frames, qi[a : a + 37], rj[a : a + 37]) for a in range(0, 2000, 37)]
    np.testing.assert_array_equal(whole.d, np.concatenate([p.d for p in parts]))
    np.testing.assert_array_equal(whole.shift_px, np.concatenate([p.shift_px for p in parts]))
    alone = [sad_pairs(frames, qi[a : a + 1], rj[a : a + 1]).d[0] for a in range(0, 2000, 10)]
    np.testing.assert_array_equal(whole.d[::10], alone)
