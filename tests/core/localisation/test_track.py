"""The continuous track's own rules on hand-made cases: fixes while standing, edges across the heading, a
guessed heading checked by b(i)'s step, a wrong heading corrected by the fixes, a strayed track re-anchored."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from driftmap.core.localisation.track import TRACK_DEFAULT, TrackState, check_heading, correct, predict
from driftmap.core.localisation.tunnels import snap
from driftmap.core.odometry.step import OdometryStep

CENTRES = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0]])  # an east-west tunnel, nodes 5 m apart
EDGES = np.array([[0, 1], [1, 2]], dtype=np.int64)
TOL_M = 0.05


def step(dx_m: float, dtheta_rad: float = 0.0) -> OdometryStep:
    return OdometryStep(
        dx_m=dx_m,
        dtheta_rad=dtheta_rad,
        shift_px=(0.0, dx_m * 100),
        confidence=0.9,
        stationary=dx_m == 0.0,
        sigma_xy_m=0.01 + 0.03 * abs(dx_m),
        sigma_theta_rad=0.002,
        prev_T_curr=(dx_m, 0.0, dtheta_rad),
        model="linear",
    )


def heading(state: TrackState, yaw_rad: float) -> TrackState:
    return replace(state, wT=np.r_[state.wT[:2], yaw_rad])


class TestFixesWhileStanding:
    def test_a_standing_vehicle_is_not_dragged_to_the_node_centre(self) -> None:
        p = TRACK_DEFAULT
        track = heading(TrackState.at((7.0, 0.0), 1.0, trusted=True), 0.0)
        for _ in range(200):  # 20 s standing 2 m from b(i)'s centre
            track = predict(track, step(0.0), 0.1, p)
            track, _ = correct(track, CENTRES[1], True, True, p, travel_m=0.0)
        assert track.wT[0] == pytest.approx(7.0, abs=TOL_M)

    def test_without_odometry_every_fix_counts(self) -> None:
        p = TRACK_DEFAULT
        track = TrackState.at((7.0, 0.0), 1.0, trusted=True)
        for _ in range(200):
            track = predict(track, None, 0.1, p)
            track, _ = correct(track, CENTRES[1], True, False, p)
        assert track.wT[0] == pytest.approx(5.0, abs=TOL_M)


class TestEdgesAcrossTheHeading:
    def test_a_vehicle_turned_into_a_stub_leaves_the_tunnel(self) -> None:
        track = heading(TrackState.at((5.0, -1.5), 1.0), -math.pi / 2)  # facing south, 1.5 m off the tunnel
        off = snap(track, CENTRES, EDGES, True, TRACK_DEFAULT, steered=True)
        assert off.wT[1] == pytest.approx(-1.5)

    def test_a_vehicle_along_the_tunnel_is_put_on_it(self) -> None:
        track = heading(TrackState.at((5.0, -1.5), 1.0), 0.1)
        on = snap(track, CENTRES, EDGES, True, TRACK_DEFAULT, steered=True)
        assert on.wT[1] == pytest.approx(0.0)

    def test_no_heading_pull_while_turning(self) -> None:
        track = heading(TrackState.at((5.0, 0.0), 1.0), 0.2)
        turning = snap(track, CENTRES, EDGES, True, TRACK_DEFAULT, steered=True, turning=True)
        straight = snap(track, CENTRES, EDGES, True, TRACK_DEFAULT, steered=True)
        assert turning.wT[2] == pytest.approx(0.2)
        assert straight.wT[2] < 0.2


class TestHeadingCheck:
    def test_a_wrong_guess_is_turned_by_the_first_step(self) -> None:
        p = TRACK_DEFAULT
        track = heading(TrackState.at((5.0, 0.0), 1.0), math.pi)  # guessed west; b(i) steps east
        checked = check_heading(track, CENTRES[1], CENTRES[2], 1.0, p)
        assert math.cos(checked.wT[2]) == pytest.approx(1.0)
        assert checked.heading_checked and checked.var_m2 >= (2 * p.fix_sigma_m) ** 2
        again = check_heading(checked, CENTRES[2], CENTRES[1], 1.0, p)  # later steps back: b(i) lagging
        assert again.wT[2] == checked.wT[2]

    def test_reversing_is_checked_the_other_way(self) -> None:
        track = heading(TrackState.at((5.0, 0.0), 1.0), math.pi)  # faces west, reverses east
        checked = check_heading(track, CENTRES[1], CENTRES[2], -1.0, TRACK_DEFAULT)
        assert checked.wT[2] == pytest.approx(math.pi)

    def test_a_step_of_a_b_i_elsewhere_says_nothing(self) -> None:
        track = heading(TrackState.at((5.0, 12.0), 1.0), math.pi)  # a parallel tunnel 12 m north
        unchecked = check_heading(track, CENTRES[1], CENTRES[2], 1.0, TRACK_DEFAULT)
        assert unchecked.wT[2] == pytest.approx(math.pi) and not unchecked.heading_checked

    def test_stored_without_the_flag_counts_as_checked(self) -> None:
        track = heading(TrackState.at((5.0, 0.0), 1.0), 0.0)
        assert TrackState.from_arrays(track.to_arrays()[:8]).heading_checked
        assert not TrackState.from_arrays(track.to_arrays()).heading_checked
        assert TrackState.from_arrays(track.to_arrays()[:9]).flip_left_m == 0.0
        sideways = replace(track, flip_left_m=-3.5)
        assert TrackState.from_arrays(sideways.to_arrays()).flip_left_m == -3.5


def drive_east(track: TrackState, frames: int, sure: bool = True) -> tuple[TrackState, list[float]]:
    """Drive ``frames`` frames east at 0.5 m per frame from x = 0 with place fixes at the true position (the
    vehicle's own heading, not the track's, is east), ``sure`` ones or doubtful; the track's heading after
    each frame."""
    p, yaws = TRACK_DEFAULT, []
    for k in range(1, frames + 1):
        track = predict(track, step(0.5), 0.1, p)
        track, _ = correct(track, np.array([0.5 * k, 0.0]), True, True, p, travel_m=0.5, steers=sure)
        yaws.append(float(track.wT[2]))
    return track, yaws


class TestHeadingFromTheFixes:
    @pytest.mark.parametrize("wrong_rad", [math.pi / 2, -math.pi / 2, 0.8, math.pi])
    def test_a_wrong_heading_is_turned_to_the_way_the_fixes_go(self, wrong_rad: float) -> None:
        # set along a crossing tunnel (pi/2), half-way round a junction (0.8) or the other way (pi): where
        # no edge along the heading would pull it back, the fixes' innovations show the angle
        start = replace(heading(TrackState.at((0.0, 0.0), 0.5, trusted=True), wrong_rad), speed_mps=5.0)
        track, _ = drive_east(start, 40)
        assert abs(math.atan2(math.sin(track.wT[2]), math.cos(track.wT[2]))) < 0.3
        assert float(np.hypot(track.wT[0] - 20.0, track.wT[1])) < 3.0

    def test_doubtful_fixes_do_not_turn_it(self) -> None:
        start = replace(heading(TrackState.at((0.0, 0.0), 0.5, trusted=True), math.pi / 2), speed_mps=5.0)
        _, sure = drive_east(start, 20)
        _, doubtful = drive_east(start, 20, sure=False)  # 10 m driven, within the gate: no re-anchor
        assert abs(sure[-1]) < 0.3 and doubtful[-1] == pytest.approx(math.pi / 2)

    def test_a_right_heading_stays(self) -> None:
        start = replace(heading(TrackState.at((0.0, 0.0), 0.5, trusted=True), 0.05), speed_mps=5.0)
        _, yaws = drive_east(start, 60)
        assert max(abs(y - 0.05) for y in yaws) < 1e-9


class TestStrayed:
    def test_sure_fixes_far_from_the_track_take_its_confidence_then_move_it(self) -> None:
        p = TRACK_DEFAULT
        track = heading(TrackState.at((0.0, 0.0), 0.5, trusted=True), 0.0)
        fix = np.array([0.0, p.stray_m + 1.0])  # beside the track, inside the gate
        for k in range(1, p.stray_frames):
            track, disagree = correct(track, fix, True, True, p, travel_m=0.5)
            assert disagree and track.strayed == k and track.wT[1] < fix[1] - 2.0
        track, disagree = correct(track, fix, True, True, p, travel_m=0.5)
        assert not disagree and tuple(track.wT[:2]) == pytest.approx(tuple(fix))
        assert not track.has_heading  # re-acquired from the tunnel it is on

    def test_doubtful_fixes_do_not(self) -> None:
        p = TRACK_DEFAULT
        track = heading(TrackState.at((0.0, 0.0), 0.5, trusted=True), 0.0)
        for _ in range(2 * p.stray_frames):
            track, disagree = correct(
                track, np.array([0.0, p.stray_m + 1.0]), True, True, p, 0.5, steers=False
            )
            assert not disagree
        assert track.strayed == 0 and track.has_heading

    def test_stored_and_read_back(self) -> None:
        track = replace(heading(TrackState.at((1.0, 2.0), 0.5), 0.3), strayed=3, flip_left_m=-1.5)
        back = TrackState.from_arrays(track.to_arrays())
        assert (back.strayed, back.flip_left_m) == (3, -1.5)
        assert TrackState.from_arrays(track.to_arrays()[:10]).strayed == 0


class TestCoasting:
    def moving(self) -> TrackState:
        track = heading(TrackState.at((0.0, 0.0), 0.5, trusted=True), 0.0)
        for _ in range(10):
            track = predict(track, step(0.3), 0.1, TRACK_DEFAULT)  # 3 m/s east
        return track

    def test_an_unusable_step_of_a_moving_vehicle_coasts_on_fading(self) -> None:
        p = TRACK_DEFAULT
        track = self.moving()
        x0, v0 = float(track.wT[0]), track.speed_mps
        one = predict(track, None, 0.1, p)
        two = predict(one, None, 0.1, p)
        assert one.wT[0] - x0 == pytest.approx(v0 * 0.1)
        assert two.wT[0] - one.wT[0] == pytest.approx(v0 * p.coast_fade * 0.1)
        assert two.var_m2 > track.var_m2

    def test_a_long_gap_coasts_at_most_coast_max_s(self) -> None:
        track = self.moving()
        after = predict(track, None, 30.0, TRACK_DEFAULT)
        assert after.wT[0] - track.wT[0] == pytest.approx(track.speed_mps * TRACK_DEFAULT.coast_max_s)

    def test_without_a_measured_speed_it_holds(self) -> None:
        track = heading(TrackState.at((2.0, 0.0), 0.5, trusted=True), 0.0)  # no odometry yet: speed NaN
        after = predict(track, None, 0.1, TRACK_DEFAULT)
        assert after.wT[0] == 2.0 and math.isnan(after.speed_mps)


class TestOdometryScale:
    def test_a_track_whose_odometry_reads_short_learns_its_scale(self) -> None:
        p = TRACK_DEFAULT
        track = heading(TrackState.at((0.0, 0.0), 0.5, trusted=True), 0.0)
        truth_m = 0.0
        lags = []
        for k in range(1500):  # 450 m east; the odometry says 0.285 m of every 0.3 m driven (5 % short)
            truth_m += 0.3
            track = predict(track, step(0.285), 0.1, p)
            fix = np.array([5.0 * round(truth_m / 5.0), 0.0])  # b(i)'s centre: the node it is in, unbiased
            track, _ = correct(track, fix, True, True, p, travel_m=0.285)
            if k >= 1000:
                lags.append(truth_m - track.wT[0])
        assert track.scale == pytest.approx(0.3 / 0.285, abs=0.01)
        assert abs(float(np.mean(lags))) < 0.3  # without the scale it stays about 2 m behind

    def test_doubtful_fixes_teach_no_scale(self) -> None:
        p = TRACK_DEFAULT
        track = heading(TrackState.at((0.0, 0.0), 0.5, trusted=True), 0.0)
        for k in range(300):
            track = predict(track, step(0.3), 0.1, p)
            track, _ = correct(track, np.array([0.3 * k + 3.0, 0.0]), False, True, p, 0.3, steers=False)
        assert track.scale == 1.0

    def test_the_scale_survives_a_re_anchoring_and_the_stored_state(self) -> None:
        p = TRACK_DEFAULT
        track = replace(
            heading(TrackState.at((0.0, 0.0), 0.5, trusted=True), 0.0), scale=1.04, scale_var=1e-4
        )
        moved, _ = correct(track, np.array([200.0, 0.0]), True, True, p, travel_m=0.3)
        assert moved.wT[0] == pytest.approx(200.0) and moved.scale == 1.04
        again = TrackState.from_arrays(moved.to_arrays())
        assert (again.scale, again.scale_var) == (1.04, 1e-4)


class TestHoldingAgainstDoubtfulFixes:
    def test_a_standing_vehicle_holds_its_track_however_long_it_stands(self) -> None:
        p = TRACK_DEFAULT
        track = heading(TrackState.at((0.0, 0.0), 0.5, trusted=True), 0.0)
        for _ in range(300):  # 30 s standing while b(i) sits on a look-alike 180 m away
            track = predict(track, step(0.0), 0.1, p)
            track, disagree = correct(track, np.array([180.0, 0.0]), False, True, p, travel_m=0.0)
            assert disagree
        assert track.wT[0] == pytest.approx(0.0)

    def test_a_driving_vehicle_gives_in_after_max_hold_m(self) -> None:
        p = TRACK_DEFAULT
        track = heading(TrackState.at((0.0, 0.0), 0.5, trusted=True), 0.0)
        driven = 0.0
        while driven < 2 * p.max_hold_m:
            track = predict(track, step(0.3), 0.1, p)
            driven += 0.3
            track, disagree = correct(track, np.array([180.0 + driven, 0.0]), False, True, p, travel_m=0.3)
            if not disagree:
                break
        assert p.max_hold_m <= driven <= p.max_hold_m + 0.6
        assert track.wT[0] == pytest.approx(180.0 + driven)


class TestHeadingPull:
    def test_a_branch_beside_the_track_does_not_turn_it(self) -> None:
        centres = np.array([[0.0, 0.0], [5.0, 0.0], [10.0, 0.0], [10.0, 3.0]])
        edges = np.array([[0, 1], [1, 2], [1, 3]], dtype=np.int64)  # a branch leaves at 31 degrees
        track = heading(TrackState.at((7.0, 1.1), 0.5), 0.0)  # driving east, beside the branch
        for _ in range(50):
            track = snap(track, centres, edges, True, TRACK_DEFAULT, steered=True)
        assert track.wT[2] == pytest.approx(0.0)

    def test_a_small_drift_is_pulled_back_to_the_tunnel(self) -> None:
        track = heading(TrackState.at((7.0, 0.5), 0.5), 0.1)
        for _ in range(50):
            track = snap(track, CENTRES, EDGES, True, TRACK_DEFAULT, steered=True)
        assert abs(track.wT[2]) < 0.01
