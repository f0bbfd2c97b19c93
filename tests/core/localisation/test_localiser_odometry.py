"""The localiser with odometry: belief moved by the distance driven, a continuous track, the fallbacks."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from driftmap.core.localisation import hmm
from driftmap.core.localisation.localiser import Localiser
from driftmap.core.localisation.map import LocaliserMap
from driftmap.core.localisation.motion import OdometryFeed
from driftmap.core.localisation.track import TRACK_DEFAULT, TrackState, correct
from driftmap.core.odometry.step import OdometryStep
from driftmap.core.topomap.distances import shortest_paths
from tests.core.localisation.test_localiser import DT_S, SPACING_M, chain_map, textures, view
from tests.floor_frames import floor_texture, pinhole_camera, render

F32 = np.ndarray
FPS_DT_S = 0.1  # a 10 fps camera


def straight(dx_m: float) -> OdometryStep:
    """A usable straight odometry step of signed travel ``dx_m`` metres (0: stationary)."""
    return OdometryStep(
        dx_m=dx_m,
        dtheta_rad=0.0,
        shift_px=(0.0, dx_m * 100),
        confidence=0.9,
        stationary=dx_m == 0.0,
        sigma_xy_m=0.01 + 0.03 * abs(dx_m),
        sigma_theta_rad=0.002,
        prev_T_curr=(dx_m, 0.0, 0.0),
        model="linear",
    )


@pytest.fixture(scope="module")
def corridor() -> tuple[F32, LocaliserMap]:
    tex = textures(40, seed=5)
    return tex, chain_map(tex, seed=6)


def node_at(x_m: float) -> int:
    return round(x_m / SPACING_M)


class TestStandingNextToALookAlike:
    """A vehicle stands where its view matches a place 10 m on better than its own (the map's views of its
    place were taken in other light): without odometry the belief walks there frame by frame; odometry
    says the vehicle has not moved, so the belief stays at the known start."""

    def standing(self, corridor: tuple[F32, LocaliserMap], *, odometry: bool) -> list[float]:
        tex, lmap = corridor
        rng = np.random.default_rng(3)
        thumbs = lmap.thumbs.copy()
        thumbs[12 * 3 : 13 * 3] = np.stack([view(tex[10], rng) for _ in range(3)])  # node 12 looks like 10
        thumbs[10 * 3 : 11 * 3] = np.stack([view(tex[10] * 0.6 + tex[25] * 0.4, rng) for _ in range(3)])
        loc = Localiser(replace(lmap, thumbs=thumbs), start_node=10)
        out = []
        for k in range(60):
            motion = straight(0.0) if odometry else None
            e = loc.step(view(tex[10], rng), k * FPS_DT_S, motion=motion)
            out.append(e.x_m)
        return out

    def test_appearance_alone_walks_to_the_look_alike(self, corridor: tuple[F32, LocaliserMap]) -> None:
        xs = self.standing(corridor, odometry=False)
        assert abs(xs[-1] - 60.0) < 2.5

    def test_odometry_holds_the_belief(self, corridor: tuple[F32, LocaliserMap]) -> None:
        xs = self.standing(corridor, odometry=True)
        assert max(abs(x - 50.0) for x in xs) < 1.0


class TestContinuousTrack:
    def drive(
        self, corridor: tuple[F32, LocaliserMap], travel_m: list[float], start_x_m: float = 50.0
    ) -> tuple[list[float], list]:
        """Drive the corridor (known start) by the signed per-frame ``travel_m``; views of the true place."""
        tex, lmap = corridor
        rng = np.random.default_rng(4)
        loc = Localiser(lmap, start_node=node_at(start_x_m))
        x, truth, out = start_x_m, [], []
        for k, dx in enumerate(travel_m):
            x += dx
            truth.append(x)
            out.append(loc.step(view(tex[node_at(x)], rng), k * FPS_DT_S, motion=straight(dx)))
        return truth, out

    def test_positions_between_node_centres(self, corridor: tuple[F32, LocaliserMap]) -> None:
        truth, est = self.drive(corridor, [0.4] * 60)  # 24 m forward at 4 m/s
        errors = np.abs(np.array([e.x_m for e in est]) - truth)
        assert float(errors.mean()) < 1.0 and float(errors.max()) < 2.5
        assert len({round(e.x_m, 1) for e in est}) > 40  # not 5 node centres
        assert all(e.odometry and e.moving for e in est)
        assert est[-1].speed_mps == pytest.approx(4.0, rel=0.05)
        assert est[-1].yaw_rad == pytest.approx(0.0, abs=0.05)  # facing +x, from the travel
        assert all(e.y_m == 0.0 for e in est)  # on the tunnel

    def test_a_reversing_vehicle(self, corridor: tuple[F32, LocaliserMap]) -> None:
        truth, est = self.drive(corridor, [0.4] * 40 + [0.0] * 10 + [-0.3] * 40)
        forward, stopped, back = est[39], est[45], est[-1]
        assert forward.speed_mps > 3.5 and back.speed_mps < -2.5
        assert not stopped.moving and stopped.speed_mps == pytest.approx(0.0, abs=0.2)
        assert back.yaw_rad == pytest.approx(0.0, abs=0.1)  # still facing +x while driving backwards
        assert back.x_m < forward.x_m - 10.0
        assert abs(back.x_m - truth[-1]) < 2.0 and back.matched

    def test_the_belief_spreads_with_distance_driven_not_time(
        self, corridor: tuple[F32, LocaliserMap]
    ) -> None:
        """A stopped vehicle's belief keeps its shape; one that drives takes a transition per hop."""
        _tex, lmap = corridor
        loc = Localiser(lmap, start_node=10)
        before = loc.state().belief
        blank = np.zeros(lmap.thumbs.shape[1:], dtype=np.float32)  # every node matches it alike
        for k in range(20):
            loc.step(blank, k * FPS_DT_S, motion=straight(0.0))
        assert np.flatnonzero(loc.state().belief > 1e-6).tolist() == np.flatnonzero(before).tolist()
        for k in range(20, 20 + int(hmm.DEFAULT.odometry_hop_m / 0.5) + 1):
            loc.step(blank, k * FPS_DT_S, motion=straight(0.5))
        assert loc.state().belief[11] > 1e-3  # one hop taken


class TestLostViewsOfATrustedTrack:
    """The views tell nothing for longer than ``lost_frames`` (a covered lens) while the vehicle drives on:
    the belief restarts around the dead-reckoned track, not over the whole map."""

    def blind_stretch(self, corridor: tuple[F32, LocaliserMap], *, odometry: bool) -> tuple[Localiser, float]:
        tex, lmap = corridor
        rng = np.random.default_rng(8)
        loc = Localiser(lmap, start_node=node_at(20.0))
        grey = np.full(tex.shape[1:], 128.0, dtype=np.float32)  # noise alone: no node matches it better
        x = 20.0
        for k in range(30 + hmm.DEFAULT.lost_frames):  # the last frame is the lost_frames-th lost one
            x += 0.3
            seen = view(tex[node_at(x)] if k < 30 else grey, rng)
            loc.step(seen, k * FPS_DT_S, motion=straight(0.3) if odometry else None)
        return loc, x

    def test_with_odometry_the_belief_restarts_around_the_track(
        self, corridor: tuple[F32, LocaliserMap]
    ) -> None:
        loc, x = self.blind_stretch(corridor, odometry=True)
        belief = loc.state().belief
        support = loc.map.centres_m[belief > 0.0, 0]
        assert support.min() >= x - 15.0 and support.max() <= x + 15.0
        assert abs(loc.state().track.wT[0] - x) < 1.5

    def test_without_odometry_it_restarts_globally(self, corridor: tuple[F32, LocaliserMap]) -> None:
        loc, _x = self.blind_stretch(corridor, odometry=False)
        assert hmm.is_global(loc.state().belief)


class TestPlaceFixFromTheReferences:
    """Each node's reference frames were taken a metre apart: the one a frame matches best tells where in
    the node the vehicle is, finer than the node centre."""

    METRES = 60

    def corridor_by_metre(self, positions: bool) -> tuple[F32, LocaliserMap]:
        tex = textures(self.METRES, seed=8)  # a distinct look every metre
        rng = np.random.default_rng(9)
        n = self.METRES // int(SPACING_M)
        thumbs = np.stack([view(t, rng) for t in tex])  # node j holds metres 5 j .. 5 j + 4
        edges = np.stack([np.arange(n - 1), np.arange(1, n)], axis=1).astype(np.int64)
        return tex, LocaliserMap(
            thumbs=thumbs,
            node_ptr=np.arange(0, self.METRES + 1, int(SPACING_M), dtype=np.int64),
            centres_m=np.column_stack([np.arange(n) * SPACING_M + 2.0, np.zeros(n)]),
            adjacency_m=shortest_paths(n, edges, np.full(n - 1, SPACING_M), 50.0),
            max_adjacency_m=50.0,
            edges=edges,
            ref_xy_m=np.column_stack([np.arange(self.METRES, dtype=np.float64), np.zeros(self.METRES)])
            if positions
            else None,
        )

    @pytest.mark.parametrize("metre", [1, 13, 44])
    def test_the_first_fix_is_where_the_best_reference_was_taken(self, metre: int) -> None:
        for positions, expect_m in ((True, float(metre)), (False, (metre // 5) * SPACING_M + 2.0)):
            tex, lmap = self.corridor_by_metre(positions)
            est = Localiser(lmap).step(
                view(tex[metre], np.random.default_rng(metre)), 0.0, motion=straight(0.5)
            )
            assert est.node == metre // 5
            assert (est.x_m, est.y_m) == pytest.approx((expect_m, 0.0))

    def test_a_neighbour_matching_better_gives_the_fix_not_a_far_node(self) -> None:
        _, lmap = self.corridor_by_metre(True)
        compared = np.array([2, 3, 9], dtype=np.int64)  # b(i) = 2; node 3 is next to it, node 9 35 m away
        d = np.array([0.5, 0.2, 0.1], dtype=np.float32)
        refs = np.array([12, 15, 45], dtype=np.int64)
        np.testing.assert_allclose(lmap.place_fix(2, compared, d, refs, 7.5), [15.0, 0.0])
        np.testing.assert_allclose(lmap.place_fix(2, compared, d, refs, 0.0), [12.0, 0.0])

    def test_a_reference_out_of_the_node_gives_its_centre(self) -> None:
        _, lmap = self.corridor_by_metre(True)
        np.testing.assert_allclose(lmap.fix_m(2, 12), [12.0, 0.0])
        np.testing.assert_allclose(lmap.fix_m(2, 3), lmap.centres_m[2])
        np.testing.assert_allclose(lmap.fix_m(2, -1), lmap.centres_m[2])


class TestFallbacks:
    def test_without_a_camera_appearance_alone_is_flagged(self, corridor: tuple[F32, LocaliserMap]) -> None:
        tex, lmap = corridor
        rng = np.random.default_rng(5)
        loc = Localiser(lmap, start_node=3)
        est = [loc.step(view(tex[j], rng), k * DT_S) for k, j in enumerate([3, 4, 5])]
        assert loc.odometry is None
        assert not any(e.odometry for e in est) and all(math.isnan(e.speed_mps) for e in est)
        assert [e.node for e in est] == [3, 4, 5]


class TestOdometryFeed:
    """The camera's own odometry on rendered floor frames (the mapping pipeline's step)."""

    @pytest.fixture(scope="class")
    @classmethod
    def floor(cls) -> np.ndarray:
        return floor_texture(1600)

    def frames(self, floor: np.ndarray, xs: list[float]) -> list[np.ndarray]:
        cam = pinhole_camera()
        return [render(floor, cam, (x, 0.0, 0.0)) for x in xs]

    def test_forward_and_reverse_steps(self, floor: np.ndarray) -> None:
        feed = OdometryFeed(pinhole_camera())
        xs = [0.0, 0.3, 0.6, 0.4, 0.2]
        steps = [feed.step(f, k * FPS_DT_S) for k, f in enumerate(self.frames(floor, xs))]
        assert steps[0] is None  # no previous frame
        dx = [s.dx_m for s in steps[1:] if s is not None]
        assert dx == pytest.approx([0.3, 0.3, -0.2, -0.2], abs=0.02)

    def test_a_dropped_frame_gap_is_not_matched(self, floor: np.ndarray) -> None:
        feed = OdometryFeed(pinhole_camera())
        a, b, c = self.frames(floor, [0.0, 0.05, 0.1])
        assert feed.step(a, 0.0) is None
        assert feed.step(b, 2.0) is None  # 2 s later: the floor may have left the search range
        assert feed.step(c, 2.1) is not None  # and the next frame is matched again

    def test_a_frame_of_another_size_is_not_matched(self, floor: np.ndarray) -> None:
        feed = OdometryFeed(pinhole_camera())
        (a,) = self.frames(floor, [0.0])
        assert feed.step(a, 0.0) is None
        assert feed.step(a[:100], 0.1) is None
        assert feed.step(a, 0.2) is None  # the odd frame broke the chain


class TestTrackGate:
    """A far fix re-anchors the track, except a doubtful one against a trusted dead-reckoned track."""

    def test_far_fixes(self) -> None:
        p = TRACK_DEFAULT
        trusted = TrackState.at((0.0, 0.0), p.fix_sigma_m, trusted=True)
        far = np.array([100.0, 0.0])
        held, disagree = correct(trusted, far, False, True, p)
        assert disagree and held.wT[0] == 0.0
        moved, disagree = correct(trusted, far, True, True, p)
        assert not disagree and moved.wT[0] == 100.0 and moved.trusted
        untrusted = TrackState.at((0.0, 0.0), p.fix_sigma_m)
        moved, disagree = correct(untrusted, far, False, True, p)  # not yet confirmed: follows the fix
        assert not disagree and moved.wT[0] == 100.0 and not moved.trusted
        smoothed, disagree = correct(trusted, far, False, False, p)  # no odometry: the track only smooths
        assert not disagree and smoothed.wT[0] == 100.0

    def test_near_fix_pulls_and_confirms(self) -> None:
        p = TRACK_DEFAULT
        track = TrackState.at((0.0, 0.0), p.fix_sigma_m)
        pulled, disagree = correct(track, np.array([2.0, 0.0]), True, True, p)
        assert not disagree and 0.5 < pulled.wT[0] < 1.5 and pulled.trusted
        assert TrackState.from_arrays(pulled.to_arrays()).trusted
