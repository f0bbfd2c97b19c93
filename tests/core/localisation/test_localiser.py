"""The stateful HMM localiser ([SSLAM] III-B) on hand-made corridors whose answer is known."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest
from numpy.typing import NDArray

from driftmap.core.imaging.images import patch_normalise
from driftmap.core.localisation import hmm
from driftmap.core.localisation.localiser import Estimate, Localiser, LocaliserState
from driftmap.core.localisation.map import LocaliserMap, build_localiser_map
from driftmap.core.localisation.track import TRACK_DEFAULT
from driftmap.core.topomap.build import build_topomap
from driftmap.core.topomap.distances import shortest_paths
from driftmap.core.topomap.model import TopoMapParams
from driftmap.errors import BadInputError

SPACING_M = 5.0
FRAMES_PER_NODE = 3
DT_S = 0.5  # frame interval: A_t = max(7.5 m floor, 3.5 m) reaches one node per frame
NOISE = 12.0  # grey-level std of query noise (texture std 40): same-place d about half an unrelated one
F32 = NDArray[np.float32]


def textures(n: int, seed: int = 0) -> F32:
    """(n, 32, 64) raw float32 grey textures, distinct per node, smooth enough to survive small shifts."""
    rng = np.random.default_rng(seed)
    raw = rng.normal(0.0, 1.0, (n, 32, 64)).astype(np.float32)
    out = np.stack([cv2.GaussianBlur(r, (0, 0), 1.2) for r in raw])
    return np.asarray(128 + 40 * out / out.std(axis=(1, 2), keepdims=True), dtype=np.float32)


def view(tex: F32, rng: np.random.Generator) -> F32:
    """A noisy, pre-processed view of a raw texture."""
    return patch_normalise(tex + rng.normal(0.0, NOISE, tex.shape).astype(np.float32))


def chain_map(tex: F32, seed: int = 1) -> LocaliserMap:
    """A straight corridor: node j at (5 j, 0), FRAMES_PER_NODE noisy views each."""
    n = tex.shape[0]
    rng = np.random.default_rng(seed)
    thumbs = np.stack([view(tex[j], rng) for j in range(n) for _ in range(FRAMES_PER_NODE)])
    edges = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1).astype(np.int64)
    return LocaliserMap(
        thumbs=thumbs,
        node_ptr=np.arange(0, FRAMES_PER_NODE * n + 1, FRAMES_PER_NODE, dtype=np.int64),
        centres_m=np.column_stack([np.arange(n) * SPACING_M, np.zeros(n)]),
        adjacency_m=shortest_paths(n, edges, np.full(n - 1, SPACING_M), 50.0),
        max_adjacency_m=50.0,
        edges=edges,
    )


def run(loc: Localiser, tex: F32, path: list[int], seed: int = 2, t0_s: float = 0.0) -> list[Estimate]:
    rng = np.random.default_rng(seed)
    return [loc.step(view(tex[j], rng), t0_s + k * DT_S) for k, j in enumerate(path)]


@pytest.fixture(scope="module")
def corridor3() -> tuple[F32, LocaliserMap]:
    tex = textures(3)
    return tex, chain_map(tex)


@pytest.fixture(scope="module")
def corridor40() -> tuple[F32, LocaliserMap]:
    tex = textures(40, seed=5)
    return tex, chain_map(tex, seed=6)


class TestThreeNodeCorridor:
    def test_filter_follows_the_walk(self, corridor3: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor3
        path = [0, 0, 1, 1, 2, 2]
        est = run(Localiser(lmap, start_node=0), tex, path)
        assert [e.node for e in est] == path
        assert all(e.matched and not e.lost for e in est)  # a known start is trusted from the first frame
        # the continuous track follows the fixes (no odometry here), within a fix's sd of node 2's centre
        assert abs(est[-1].x_m - 10.0) < TRACK_DEFAULT.fix_sigma_m and est[-1].y_m == 0.0
        assert not any(e.odometry for e in est) and all(np.isnan(e.speed_mps) for e in est)

    def test_misleading_frame_fools_single_image_not_the_filter(
        self, corridor3: tuple[F32, LocaliserMap]
    ) -> None:
        tex, lmap = corridor3
        rng = np.random.default_rng(3)
        misleading = patch_normalise(0.42 * tex[0] + 0.58 * tex[2])  # at node 0, looks more like node 2
        frames = [view(tex[0], rng), view(tex[0], rng), misleading, view(tex[0], rng), view(tex[1], rng)]
        single = Localiser(lmap, single_image=True)
        filtered = Localiser(lmap, start_node=0)
        s = [single.step(f, k * DT_S).node for k, f in enumerate(frames)]
        h = [filtered.step(f, k * DT_S).node for k, f in enumerate(frames)]
        assert s == [0, 0, 2, 0, 1]
        assert h == [0, 0, 0, 0, 1]

    def test_single_image_compares_every_node(self, corridor3: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor3
        est = run(Localiser(lmap, single_image=True), tex, [1])[0]
        assert est.node == 1 and est.evaluated_nodes == 3 and 0 < est.score <= 1

    def test_raw_uint8_frame_is_preprocessed(self, corridor3: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor3
        frame = np.clip(cv2.resize(tex[2], (128, 64)), 0, 255).astype(np.uint8)  # camera frame, 2x size
        assert Localiser(lmap, single_image=True).step(frame, 0.0).node == 2


class TestPruning:
    def test_only_top_prior_states_and_probes_are_compared(
        self, corridor40: tuple[F32, LocaliserMap]
    ) -> None:
        tex, lmap = corridor40
        params = hmm.HmmParams(n_t=4, n_probe=3)
        est = run(Localiser(lmap, params, start_node=10), tex, [10, 11, 12])
        assert [e.node for e in est] == [10, 11, 12]
        assert all(e.evaluated_nodes <= 7 for e in est)

    def test_global_init_evaluates_everything_then_narrows(
        self, corridor40: tuple[F32, LocaliserMap]
    ) -> None:
        tex, lmap = corridor40
        est = run(Localiser(lmap, hmm.HmmParams(n_t=6)), tex, list(range(20, 26)))
        assert est[0].evaluated_nodes == 40
        assert all(e.evaluated_nodes <= 6 + hmm.DEFAULT.n_probe for e in est[1:])
        assert [e.node for e in est[2:]] == list(range(22, 26))  # found within a couple of frames


class TestBeyondThePaper:
    def test_kidnap_is_detected_and_relocalised(self, corridor40: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor40
        params = hmm.HmmParams(n_t=5, lost_frames=3, relocate_ratio=0.0)  # found by the global restart
        loc = Localiser(lmap, params, start_node=0)
        before = run(loc, tex, list(range(10)))
        assert [e.node for e in before] == list(range(10)) and not any(e.lost for e in before)
        after = run(loc, tex, list(range(30, 38)), t0_s=10 * DT_S)  # teleported 100 m away
        assert any(e.lost for e in after[:3])
        assert [e.node for e in after[-3:]] == [35, 36, 37]
        assert not any(e.lost for e in after[-3:])

    @pytest.mark.parametrize("relocate_ratio", [hmm.DEFAULT.relocate_ratio, 0.0])
    def test_a_far_place_that_matches_clearly_better_is_taken_up(
        self, corridor40: tuple[F32, LocaliserMap], relocate_ratio: float
    ) -> None:
        tex, lmap = corridor40
        params = hmm.HmmParams(n_t=5, lost_frames=0, relocate_ratio=relocate_ratio)  # never restarts
        loc = Localiser(lmap, params, start_node=0)
        run(loc, tex, list(range(10)))
        rng = np.random.default_rng(2)
        after, peaks = [], []
        for k, j in enumerate(range(30, 40)):  # teleported 100 m away
            after.append(loc.step(view(tex[j], rng), (10 + k) * DT_S))
            peaks.append(int(np.argmax(loc.state().belief)))
        if relocate_ratio:  # a probe sees the place: it becomes a hypothesis, and the next frames confirm it
            assert [e.node for e in after[-5:]] == [35, 36, 37, 38, 39]
            # the frame that takes it up already reports it: the estimate is the belief the frame leaves
            assert [e.node for e in after] == peaks
            first = next(k for k, e in enumerate(after) if e.node >= 30)
            assert after[first].node == 30 + first and after[first].score >= params.relocate_share
        else:
            assert all(e.node < 20 for e in after)  # without it the belief stays where it was

    def test_lost_is_reported_only_when_sustained(self, corridor40: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor40
        loc = Localiser(lmap, hmm.HmmParams(n_t=5, relocate_ratio=0.0), start_node=0)  # the count alone
        run(loc, tex, list(range(10)))
        glimpse = loc.step(view(tex[30], np.random.default_rng(3)), 10 * DT_S)  # one view of another place
        assert loc.state().lost_count == 1 and not glimpse.lost and glimpse.node in (9, 10)
        back = run(loc, tex, [10, 11, 12], t0_s=11 * DT_S)
        assert [e.node for e in back[1:]] == [11, 12] and loc.state().lost_count == 0
        away = run(loc, tex, [30, 31, 32], seed=4, t0_s=14 * DT_S)  # the other place, frame after frame
        assert loc.state().lost_count == 3
        assert [e.lost for e in away] == [False, False, True] and not away[-1].matched

    def test_a_global_restart_compares_the_whole_map(self) -> None:
        # Nodes 0-9 lie 2 m apart, 10-29 6 m apart: pi of a flat belief (eq. 9, columns normalised) favours
        # the dense ones, which have more neighbours within A_t.
        xs = np.r_[np.arange(10) * 2.0, 18.0 + np.arange(1, 21) * 6.0]
        n = xs.size
        tex = textures(n, seed=31)
        rng = np.random.default_rng(32)
        edges = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1).astype(np.int64)
        lmap = LocaliserMap(
            thumbs=np.stack([view(tex[j], rng) for j in range(n) for _ in range(FRAMES_PER_NODE)]),
            node_ptr=np.arange(0, FRAMES_PER_NODE * n + 1, FRAMES_PER_NODE, dtype=np.int64),
            centres_m=np.column_stack([xs, np.zeros(n)]),
            adjacency_m=shortest_paths(n, edges, np.diff(xs), 50.0),
            max_adjacency_m=50.0,
        )
        loc = Localiser(lmap, hmm.HmmParams(n_t=5, n_probe=0))
        flat = hmm.initial_belief(n)
        assert not hmm.is_global(loc.transitions.predict(flat, DT_S))  # what the old code compared
        loc.restore(LocaliserState(flat, 7.0, 0, 50))  # just re-initialised: a flat belief, a known last time
        est = loc.step(view(tex[25], np.random.default_rng(33)), 7.0 + DT_S)
        assert est.evaluated_nodes == n and est.node == 25

    def test_paper_preset_never_reinitialises(self, corridor40: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor40
        loc = Localiser(lmap, hmm.HmmParams(n_t=5, n_probe=0, lost_frames=0), start_node=0)
        run(loc, tex, list(range(5)))
        after = run(loc, tex, list(range(30, 36)), t0_s=5 * DT_S)
        assert not any(e.lost for e in after) and all(e.node < 20 for e in after)

    def test_stopped_vehicle_stays_put(self, corridor40: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor40
        loc = Localiser(lmap, start_node=5)
        run(loc, tex, [5, 6, 7])
        frame = view(tex[7], np.random.default_rng(9))
        est = [loc.step(frame, 3 * DT_S + k * DT_S) for k in range(20)]  # the same frame, over and over
        assert all(e.node == 7 and e.matched for e in est)

    def test_reversing(self, corridor40: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor40
        path = [*range(10, 17), *range(15, 8, -1)]
        est = run(Localiser(lmap, start_node=10), tex, path)
        assert [e.node for e in est] == path

    def test_dropped_frames_widen_the_reach(self, corridor40: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor40
        frame = view(tex[15], np.random.default_rng(4))
        nodes = []
        for gap_s in (DT_S, 3.0):  # 3 s at 7 m/s: A_t = 21 m, four nodes on in one step
            loc = Localiser(lmap, hmm.HmmParams(n_t=12, lost_frames=0), start_node=10)
            run(loc, tex, [10, 11])
            nodes.append(loc.step(frame, DT_S + gap_s).node)
        assert nodes[0] != 15 and nodes[1] == 15


class TestConfidence:
    def test_a_track_that_shows_its_place_is_confident_a_run_of_blank_frames_is_not(
        self, corridor40: tuple[F32, LocaliserMap]
    ) -> None:
        tex, lmap = corridor40
        loc = Localiser(lmap, start_node=10)
        seen = run(loc, tex, [10, 11, 12])[-1]
        assert 0.2 < seen.distinct <= 1.0
        assert seen.confidence == pytest.approx(
            hmm.calibrated(seen.score * seen.distinct, hmm.DEFAULT.calibration)
        )
        blank = np.zeros(lmap.thumbs.shape[1:], dtype=np.float32)  # matches every node alike
        first = loc.step(blank, 3 * DT_S)
        # One frame that shows nothing (its b(i) stays on the track) only pulls the track's distinctness
        # down by its weight ...
        assert abs(first.node - seen.node) <= 1
        assert first.distinct == pytest.approx((1.0 - hmm.DEFAULT.distinct_memory) * seen.distinct, abs=0.02)
        # ... a run of them takes it (and the confidence) towards zero.
        last = [loc.step(blank, k * DT_S) for k in range(4, 18)][-1]
        assert not loc.state().node < 0  # no global restart yet
        assert last.distinct < 0.05 and last.confidence < 0.5

    def test_distinctness_starts_afresh_after_a_jump(self, corridor40: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor40
        loc = Localiser(lmap, start_node=10)
        run(loc, tex, [10, 11, 12])
        state = loc.state()
        frame = view(tex[13], np.random.default_rng(9))
        alone = Localiser(lmap)
        alone.restore(replace(state, node=-1, distinct=1.0))  # after a global start: a new track, from 0
        own = alone.step(frame, 3 * DT_S).distinct
        a = hmm.DEFAULT.distinct_memory
        assert 0.0 < own < a
        outcomes = {}
        for last_node in (12, 35):  # 1 node back: the same track; 23 nodes away: a jump
            loc.restore(replace(state, node=last_node, distinct=1.0))
            outcomes[last_node] = loc.step(frame, 3 * DT_S).distinct
        assert outcomes[12] == pytest.approx((1.0 - a) + own)
        assert outcomes[35] == pytest.approx(own)

    def test_a_view_that_matches_a_far_place_as_well_is_not_distinct(
        self, corridor40: tuple[F32, LocaliserMap]
    ) -> None:
        tex, lmap = corridor40
        rng = np.random.default_rng(31)
        thumbs = lmap.thumbs.copy()
        for j in (10, 11, 12):  # nodes 30-32, 100 m on, look like nodes 10-12
            twin_of_j = slice((j + 20) * FRAMES_PER_NODE, (j + 21) * FRAMES_PER_NODE)
            thumbs[twin_of_j] = np.stack([view(tex[j], rng) for _ in range(FRAMES_PER_NODE)])
        twin = replace(lmap, thumbs=thumbs)
        params = hmm.HmmParams(n_t=40)  # every node compared
        path = [10, 11, 12, 12, 12, 12]  # long enough for the known start's trust to be forgotten
        plain = run(Localiser(lmap, params, start_node=10), tex, path)[-1]
        ambiguous = run(Localiser(twin, params, start_node=10), tex, path)[-1]
        # The filter stays on its track either way (a known start), and the views match their nodes just
        # as well; only the far twin stretch makes them ambiguous.
        assert plain.node == ambiguous.node == 12
        assert plain.distinct > 0.2
        assert ambiguous.distinct < 0.5 * plain.distinct

    def test_single_image_confidence_is_its_score(self, corridor3: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor3
        est = run(Localiser(lmap, single_image=True), tex, [1])[0]
        assert est.distinct == pytest.approx(est.score)
        assert est.confidence == pytest.approx(hmm.calibrated(est.score**2, hmm.DEFAULT.calibration))


class TestUnevenSpacing:
    def test_belief_follows_across_a_step_longer_than_the_reach(self) -> None:
        tex = textures(8, seed=21)
        rng = np.random.default_rng(22)
        xs = np.array([0.0, 5.0, 10.0, 15.0, 24.0, 29.0, 34.0, 39.0])  # 9 m between nodes 3 and 4
        edges = np.stack([np.arange(7), np.arange(1, 8)], axis=1).astype(np.int64)
        lmap = LocaliserMap(
            thumbs=np.stack([view(tex[j], rng) for j in range(8) for _ in range(FRAMES_PER_NODE)]),
            node_ptr=np.arange(0, FRAMES_PER_NODE * 8 + 1, FRAMES_PER_NODE, dtype=np.int64),
            centres_m=np.column_stack([xs, np.zeros(8)]),
            adjacency_m=shortest_paths(8, edges, np.diff(xs), 50.0),
            max_adjacency_m=50.0,
        )
        np.testing.assert_array_equal(lmap.long_steps(hmm.DEFAULT.min_a_t_m), [[3, 4]])
        path = [0, 1, 2, 3, 3, 4, 5, 6, 7]
        est = run(Localiser(lmap, hmm.HmmParams(n_t=3), start_node=0), tex, path)  # A_t = 8 m < 9 m
        assert [e.node for e in est] == path
        # A filter that may reach 10 m a frame needs no long step; one limited to 4 m takes every 5 m
        # spacing as a long step too, and follows the same drive.
        assert lmap.long_steps(10.0).shape == (0, 2)
        short = hmm.HmmParams(n_t=3, min_a_t_m=4.0, max_speed_mps=0.5)
        assert Localiser(lmap, short).transitions.reach_m(0.1) < 5.0
        est = run(Localiser(lmap, short, start_node=0), tex, path)
        assert [e.node for e in est] == path


class TestStillFrames:
    """A vehicle standing where the view matches the map poorly: the same view again is no new evidence."""

    def walk_then_stand(
        self, still_ratio: float, lost_report_frames: int = 3
    ) -> tuple[Localiser, list[Estimate], list[Estimate]]:
        tex, lmap = self.tex, self.lmap
        params = hmm.HmmParams(  # every node compared
            n_t=40, lost_frames=3, still_ratio=still_ratio, lost_report_frames=lost_report_frames
        )
        loc = Localiser(lmap, params)  # global start: confirmed only by moving frames
        walk = run(loc, tex, list(range(2, 16)))
        # standing at 16, the view matches a look-alike 80 m away a little better than its own place (d 0.60
        # against 0.70, d(16) / d(32) 1.17, below relocate_ratio: like the simulated medium site's long stand)
        looks_far = view(0.55 * tex[32] + 0.45 * tex[16], np.random.default_rng(30))
        stand = [loc.step(looks_far, (14 + k) * DT_S) for k in range(8)]
        return loc, walk, stand

    @pytest.fixture(autouse=True)
    def _map(self, corridor40: tuple[F32, LocaliserMap]) -> None:
        self.tex, self.lmap = corridor40

    def test_standing_never_reinitialises_a_confirmed_belief(self) -> None:
        loc, walk, stand = self.walk_then_stand(hmm.DEFAULT.still_ratio)
        assert [e.node for e in walk[-3:]] == [13, 14, 15]
        assert loc.state().lost_count == 1  # only the first, changed view counted
        assert not any(e.lost for e in stand)  # 1 counted lost frame is below lost_report_frames
        assert all(abs(e.node - 15) <= 2 for e in stand)
        after = run(loc, self.tex, [16, 17, 18], seed=31, t0_s=22 * DT_S)
        assert [e.node for e in after] == [16, 17, 18]

    def test_reporting_every_lost_frame_reports_the_whole_stand_lost(self) -> None:
        loc, _walk, stand = self.walk_then_stand(hmm.DEFAULT.still_ratio, lost_report_frames=1)
        assert loc.state().lost_count == 1
        assert all(e.lost and not e.matched for e in stand)
        assert all(abs(e.node - 15) <= 2 for e in stand)

    def test_without_still_frames_the_belief_is_thrown_away(self) -> None:
        _loc, walk, stand = self.walk_then_stand(0.0)
        # re-initialised at the look-alike; a new track is less sure than the long one it replaced
        assert stand[-1].node == 32 and stand[-1].confidence < walk[-1].confidence

    def test_a_new_global_start_is_not_held(self) -> None:
        lmap = self.lmap
        loc = Localiser(lmap, hmm.HmmParams(n_t=5, lost_frames=3))
        blank = np.zeros(lmap.thumbs.shape[1:], dtype=np.float32)
        for k in range(3):
            loc.step(blank, k * DT_S)  # nothing confirmed yet: lost frames count even when still
        assert loc.state().moving <= 1
        np.testing.assert_allclose(loc.state().belief, 1.0 / lmap.n_nodes)  # re-initialised


class TestState:
    def test_save_restore_gives_identical_estimates(self, corridor40: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor40
        loc = Localiser(lmap, start_node=3)
        run(loc, tex, [3, 4, 5, 6])
        saved = LocaliserState.from_arrays(loc.state().to_arrays())
        twin = Localiser(lmap)
        twin.restore(saved)
        path = [7, 8, 9, 30, 31]
        a = run(loc, tex, path, seed=11, t0_s=2.0)
        b = run(twin, tex, path, seed=11, t0_s=2.0)
        strip = [(e.node, e.score, e.matched, e.lost, e.evaluated_nodes, e.distinct) for e in a]
        assert strip == [(e.node, e.score, e.matched, e.lost, e.evaluated_nodes, e.distinct) for e in b]
        np.testing.assert_array_equal(loc.state().belief, twin.state().belief)

    def test_state_stored_before_still_frames_still_loads(self, corridor40: tuple[F32, LocaliserMap]) -> None:
        _tex, lmap = corridor40
        arrays = Localiser(lmap, start_node=3).state().to_arrays()
        newer = ("moving", "last_query", "node", "distinct")
        assert set(newer) <= set(arrays)
        state = LocaliserState.from_arrays({k: v for k, v in arrays.items() if k not in newer})
        assert state.moving == 0 and state.last_query.shape == (0, 0)
        assert state.node == -1 and state.distinct == 0.0


class TestBuildLocaliserMap:
    def test_nearest_node(self, corridor3: tuple[F32, LocaliserMap]) -> None:
        _tex, lmap = corridor3
        assert [lmap.nearest_node(x, 1.0) for x in (-3.0, 0.5 * SPACING_M + 0.1, 99.0)] == [0, 1, 2]
        with pytest.raises(BadInputError, match="finite"):
            lmap.nearest_node(float("nan"), 0.0)

    def test_takes_each_nodes_chosen_frames(self) -> None:
        xs = np.arange(0.0, 30.0, 0.5)
        poses = np.column_stack([xs, np.zeros_like(xs), np.zeros_like(xs)])
        topo = build_topomap([poses], params=TopoMapParams(frames_per_node=2))
        flat_thumbs = np.zeros((xs.size, 32, 64), dtype=np.float32)
        flat_thumbs[:, 0, 0] = np.arange(xs.size)  # tag each thumbnail with its flat frame index
        lmap = build_localiser_map(topo, flat_thumbs)
        assert lmap.n_nodes == topo.n_nodes
        for j in range(topo.n_nodes):
            tags = lmap.thumbs[lmap.node_ptr[j] : lmap.node_ptr[j + 1], 0, 0].astype(np.int64)
            np.testing.assert_array_equal(tags, topo.chosen[topo.chosen_ptr[j] : topo.chosen_ptr[j + 1]])
