"""HMM building blocks ([SSLAM] III-B): node comparison (eq. 4), gamma (eq. 8), pi (eq. 9-10), update."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.typing import NDArray
from scipy.sparse import csr_array

from driftmap.core.imaging.images import patch_normalise
from driftmap.core.imaging.params import SadParams
from driftmap.core.imaging.sad import sad_one_to_many
from driftmap.core.localisation import hmm, transitions
from driftmap.core.topomap.distances import shortest_paths
from driftmap.errors import BadInputError

SPACING_M = 5.0
SAD_TOL = 1e-5  # float32 SAD agreement between the gathered and the direct comparison
EPS = 0.01


def chain_adjacency(n: int, max_m: float = 50.0) -> csr_array:
    """Shortest paths of an n-node chain with ``SPACING_M`` between consecutive nodes."""
    edges = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1).astype(np.int64)
    return shortest_paths(n, edges, np.full(n - 1, SPACING_M), max_m)


def thumbs(n: int, seed: int = 0) -> NDArray[np.float32]:
    """(n, 32, 64) patch-normalised random textures."""
    rng = np.random.default_rng(seed)
    return patch_normalise(rng.normal(128, 40, (n, 32, 64)).astype(np.float32))


class TestCompareNodes:
    def test_min_over_each_nodes_frames(self) -> None:
        refs = thumbs(7)
        ptr = np.array([0, 3, 3, 5, 7], dtype=np.int64)  # node 1 holds no frame
        query = refs[4]
        d = hmm.compare_nodes(query, refs, ptr, np.array([3, 1, 0, 2], dtype=np.int64))
        direct = sad_one_to_many(query, refs).d
        expect = [direct[5:7].min(), np.inf, direct[0:3].min(), direct[3:5].min()]
        np.testing.assert_allclose(d, expect, atol=SAD_TOL)
        assert d[3] == pytest.approx(0.0, abs=SAD_TOL)  # the query is frame 4, a frame of node 2

    def test_only_requested_nodes_are_compared(self, monkeypatch: pytest.MonkeyPatch) -> None:
        refs = thumbs(30)
        ptr = np.arange(0, 31, 3, dtype=np.int64)  # 10 nodes of 3 frames
        seen: list[int] = []

        def counting(query: NDArray[np.float32], r: NDArray[np.float32], params: SadParams) -> object:
            seen.append(r.shape[0])
            return sad_one_to_many(query, r, params)

        monkeypatch.setattr(hmm, "sad_one_to_many", counting)
        hmm.compare_nodes(refs[0], refs, ptr, np.array([2, 7], dtype=np.int64))
        assert seen == [6]

    def test_all_nodes_in_order(self) -> None:
        refs = thumbs(6)
        ptr = np.array([0, 2, 4, 6], dtype=np.int64)
        d = hmm.compare_nodes(refs[2], refs, ptr, np.arange(3, dtype=np.int64))
        assert int(np.argmin(d)) == 1

    def test_the_reference_that_gave_each_score(self) -> None:
        refs = thumbs(7)
        ptr = np.array([0, 3, 3, 5, 7], dtype=np.int64)  # node 1 holds no frame
        d, best = hmm.compare_references(refs[4], refs, ptr, np.array([2, 1, 0], dtype=np.int64))
        direct = sad_one_to_many(refs[4], refs).d
        assert best.tolist() == [4, -1, int(np.argmin(direct[0:3]))]
        np.testing.assert_allclose(d, [0.0, np.inf, direct[0:3].min()], atol=SAD_TOL)

    def test_bad_node_index(self) -> None:
        refs = thumbs(3)
        with pytest.raises(BadInputError):
            hmm.compare_nodes(refs[0], refs, np.array([0, 3], dtype=np.int64), np.array([1], dtype=np.int64))


class TestObservation:
    def test_eq8_on_hand_values(self) -> None:
        # d_max = 5, d_min = 1: (5 - d) / 4 = 1, 0.75, 0.5, 0; p_t = 0.6 turns 0.5 and 0 into epsilon.
        gamma = hmm.observation(np.array([1.0, 2.0, 3.0, 5.0]), p_t=0.6, epsilon=EPS)
        np.testing.assert_allclose(gamma, [1.0, 0.75, EPS, EPS])

    def test_p_t_is_inclusive(self) -> None:
        gamma = hmm.observation(np.array([1.0, 3.0, 5.0]), p_t=0.5, epsilon=EPS)
        np.testing.assert_allclose(gamma, [1.0, 0.5, EPS])

    def test_equal_scores_tell_nothing(self) -> None:
        np.testing.assert_allclose(hmm.observation(np.array([2.0, 2.0]), 0.5, EPS), [1.0, 1.0])

    @settings(max_examples=50, deadline=None)
    @given(st.lists(st.floats(0.0, 10.0), min_size=2, max_size=30), st.floats(0.0, 1.0))
    def test_range_best_and_order(self, values: list[float], p_t: float) -> None:
        d = np.asarray(values)
        gamma = hmm.observation(d, p_t, EPS)
        assert np.all((gamma == EPS) | ((gamma >= p_t) & (gamma <= 1.0)))
        assert gamma[int(np.argmin(d))] == 1.0
        kept = gamma > EPS
        assert np.all(np.diff(gamma[kept][np.argsort(d[kept])]) <= 0)  # smaller d, larger gamma

    def test_node_without_frames_is_a_poor_match(self) -> None:
        gamma = hmm.observation(np.array([1.0, np.inf, 2.0]), 0.5, EPS)
        np.testing.assert_allclose(gamma, [1.0, EPS, EPS])  # d_max = 2 from the finite scores


class TestTransitions:
    def test_columns_sum_to_one(self) -> None:
        model = transitions.TransitionModel(chain_adjacency(12), 50.0, hmm.DEFAULT)
        for gap_s in (0.1, 1.0, 3.0, 6.0):
            pi = model.matrix(model.reach_m(gap_s))
            assert pi is not None
            np.testing.assert_allclose(pi.sum(axis=0), 1.0)

    def test_gap_of_three_intervals_reaches_three_times_further(self) -> None:
        params = hmm.HmmParams(max_speed_mps=6.0, min_a_t_m=1.0)  # one 1 s interval: A_t = 6 m, one node
        model = transitions.TransitionModel(chain_adjacency(20), 50.0, params)
        start = np.zeros(20)
        start[10] = 1.0
        one = np.flatnonzero(model.predict(start, 1.0))
        three = np.flatnonzero(model.predict(start, 3.0))  # A_t = 18 m: three nodes each way
        np.testing.assert_array_equal(one, [9, 10, 11])
        np.testing.assert_array_equal(three, np.arange(7, 14))

    def test_cached_by_quantised_reach(self) -> None:
        params = hmm.HmmParams(max_speed_mps=7.0, min_a_t_m=1.0, a_t_quantum_m=1.0)
        model = transitions.TransitionModel(chain_adjacency(10), 50.0, params)
        belief = np.full(10, 0.1)
        for gap_s in (1.0, 0.99, 0.95, 1.0, 2.0):  # 7, 6.93, 6.65 -> 7 m; 14 m
            model.predict(belief, gap_s)
        assert model.cached == 2

    def test_reach_beyond_stored_paths_is_global(self) -> None:
        model = transitions.TransitionModel(chain_adjacency(30, max_m=20.0), 20.0, hmm.DEFAULT)
        start = np.zeros(30)
        start[0] = 1.0
        np.testing.assert_allclose(model.predict(start, 60.0), 1.0 / 30)

    def test_stopping_keeps_mass_and_reversing_is_symmetric(self) -> None:
        model = transitions.TransitionModel(chain_adjacency(5), 50.0, hmm.DEFAULT)
        pi = model.matrix(model.reach_m(0.0))
        assert pi is not None
        dense = pi.toarray()
        assert np.all(np.diag(dense) > 0)  # motion-agnostic: staying is always possible
        np.testing.assert_array_equal(dense > 0, (dense > 0).T)  # back as likely reachable as forward


class TestLongSteps:
    """Direct steps between nodes longer than the reach (uneven spacing at junctions and merges)."""

    @staticmethod
    def uneven_chain() -> csr_array:
        xs = np.array([0.0, 5.0, 10.0, 19.0, 24.0])  # a 9 m step between nodes 2 and 3
        edges = np.stack([np.arange(4), np.arange(1, 5)], axis=1).astype(np.int64)
        return shortest_paths(5, edges, np.diff(xs), 50.0)

    def test_only_direct_steps_are_found(self) -> None:
        steps = transitions.long_steps(self.uneven_chain(), 7.5)
        np.testing.assert_array_equal(steps, [[2, 3]])  # 0-2 (10 m) and 1-3 (14 m) pass through a node
        assert transitions.long_steps(self.uneven_chain(), 10.0).shape == (0, 2)

    def test_transitions_cross_a_long_step_in_one_frame(self) -> None:
        adj = self.uneven_chain()
        start = np.zeros(5)
        start[2] = 1.0
        plain = transitions.TransitionModel(adj, 50.0, hmm.DEFAULT)  # A_t = 8 m < 9 m: a wall
        crossing = transitions.TransitionModel(adj, 50.0, hmm.DEFAULT, steps=transitions.long_steps(adj, 7.5))
        assert plain.predict(start, 0.1)[3] == 0.0
        prior = crossing.predict(start, 0.1)
        assert prior[3] > 0 and prior[4] == 0.0  # the next node, not beyond it
        pi = crossing.matrix(crossing.reach_m(0.1))
        assert pi is not None
        np.testing.assert_allclose(pi.sum(axis=0), 1.0)
        np.testing.assert_array_equal(pi.toarray() > 0, (pi.toarray() > 0).T)


class TestSelectStates:
    def test_top_n_t(self) -> None:
        prior = np.array([0.05, 0.4, 0.1, 0.3, 0.15])
        np.testing.assert_array_equal(hmm.select_states(prior, 2), [1, 3])

    def test_flat_belief_evaluates_everything(self) -> None:
        np.testing.assert_array_equal(hmm.select_states(np.full(50, 0.02), 5), np.arange(50))
        assert hmm.is_global(np.full(50, 0.02)) and not hmm.is_global(np.r_[np.full(49, 0.02), 0.0201])


class TestUpdate:
    def test_eq5_6_on_hand_values(self) -> None:
        prior = np.array([0.5, 0.3, 0.2])
        post = hmm.hmm_update(prior, np.array([0, 1]), np.array([1.0, 0.5]), epsilon=0.1)
        expect = np.array([0.5, 0.15, 0.02])
        np.testing.assert_allclose(post, expect / expect.sum())

    def test_a_hypothesis_takes_its_share(self) -> None:
        x = hmm.add_hypothesis(np.array([0.0, 0.6, 0.4, 0.0]), 3, 0.5)
        np.testing.assert_allclose(x, [0.0, 0.3, 0.2, 0.5])

    def test_initial_beliefs(self) -> None:
        np.testing.assert_allclose(hmm.initial_belief(4), 0.25)
        centres = np.column_stack([np.arange(5) * SPACING_M, np.zeros(5)])
        x = hmm.initial_belief(5, 2, centres, radius_m=SPACING_M)
        np.testing.assert_allclose(x, [0, 1 / 3, 1 / 3, 1 / 3, 0])


class TestParams:
    @pytest.mark.parametrize(
        "field", ["max_speed_mps", "epsilon", "n_t", "lost_report_frames", "relocate_share"]
    )
    def test_rejects_non_positive(self, field: str) -> None:
        with pytest.raises(BadInputError):
            hmm.HmmParams(**{field: 0})

    @pytest.mark.parametrize("field", ["still_ratio", "confirm_frames", "relocate_ratio"])
    def test_rejects_negative(self, field: str) -> None:
        with pytest.raises(BadInputError):
            hmm.HmmParams(**{field: -1})

    def test_presets(self) -> None:
        assert hmm.PAPER.lost_frames == 0 and hmm.DEFAULT.lost_frames > 0
        assert hmm.PAPER.relocate_ratio == 0 and hmm.DEFAULT.relocate_ratio > 1
        assert hmm.DEFAULT.max_speed_mps == 7.0
