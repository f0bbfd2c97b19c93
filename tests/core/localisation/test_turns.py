"""Turns driven against the map's turns: the mapped turn table, the driven history, and look-alike branches
that appearance cannot tell apart but a corner can."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from driftmap.core.localisation import hmm
from driftmap.core.localisation.localiser import Localiser
from driftmap.core.localisation.map import LocaliserMap
from driftmap.core.localisation.turns import TURNS_DEFAULT, TurnHistory, map_turns, turn_likelihood
from driftmap.core.odometry.step import OdometryStep
from driftmap.core.topomap.distances import shortest_paths
from driftmap.errors import BadInputError
from tests.core.localisation.test_localiser import FRAMES_PER_NODE, SPACING_M, textures, view

QUARTER_RAD = math.pi / 2
N_BRANCH = 16  # nodes per branch, 5 m apart: 75 m of tunnel
CORNER = 7  # branch B turns left at its node 7 (35 m along)
STEP_M = 0.5  # odometry step per frame
TURN_TOL_RAD = 0.05  # the mapped turn of a clean right angle, to node-centre rounding


def l_shape(n: int = N_BRANCH, corner: int = CORNER, y0_m: float = 0.0) -> np.ndarray:
    """(n, 2) node centres: along +x to node ``corner``, then along +y, 5 m apart."""
    s = np.arange(n) * SPACING_M
    c = corner * SPACING_M
    return np.column_stack([np.minimum(s, c), y0_m + np.maximum(s - c, 0.0)])


def chain_edges(n: int, offset: int = 0) -> np.ndarray:
    return np.stack([np.arange(n - 1), np.arange(1, n)], axis=1).astype(np.int64) + offset


class TestMapTurns:
    def test_a_straight_tunnel_has_no_turn(self) -> None:
        centres = np.column_stack([np.arange(10) * SPACING_M, np.zeros(10)])
        turns = map_turns(centres, chain_edges(10))
        assert np.nanmax(turns) < TURN_TOL_RAD
        assert np.isfinite(turns[5]).any()

    def test_a_corner_within_the_window(self) -> None:
        turns = map_turns(l_shape(), chain_edges(N_BRANCH))
        after = turns[CORNER + 2]  # 10 m past the corner: the path 15 m back goes round it
        assert np.nanmin(np.abs(after - QUARTER_RAD)) < TURN_TOL_RAD
        far = turns[0]  # 35 m before it: only straight paths of 15 m
        assert np.nanmax(far) < TURN_TOL_RAD

    def test_no_path_that_long_is_no_evidence(self) -> None:
        centres = np.column_stack([np.arange(2) * SPACING_M, np.zeros(2)])
        turns = map_turns(centres, chain_edges(2))
        assert np.isnan(turns).all()
        assert np.allclose(turn_likelihood(QUARTER_RAD, turns), 1.0)

    def test_likelihood_favours_agreeing_nodes(self) -> None:
        turns = map_turns(l_shape(), chain_edges(N_BRANCH))
        f = turn_likelihood(QUARTER_RAD, turns)
        assert f[CORNER + 2] == pytest.approx(1.0, abs=0.01)
        assert f[0] == pytest.approx(TURNS_DEFAULT.floor, abs=0.1)
        assert (f >= TURNS_DEFAULT.floor).all()


class TestTurnHistory:
    def drive(self, steps: list[tuple[float, float]]) -> tuple[TurnHistory, list[float]]:
        history, turns = TurnHistory.empty(), []
        for dx_m, dtheta_rad in steps:
            history, turn = history.advance(dx_m, dtheta_rad, TURNS_DEFAULT)
            if turn is not None:
                turns.append(turn)
        return history, turns

    def test_a_window_round_a_corner(self) -> None:
        steps = [(1.0, 0.0)] * 20 + [(1.0, QUARTER_RAD / 4)] * 4 + [(1.0, 0.0)] * 20
        _history, turns = self.drive(steps)
        assert len(turns) >= 10, "a checked window every 2.5 m once 15 m were driven"
        assert turns[0] < TURN_TOL_RAD  # the first window is before the corner,
        assert max(turns) == pytest.approx(QUARTER_RAD, abs=TURN_TOL_RAD)  # later ones span it,
        assert turns[-1] < TURN_TOL_RAD  # the last ones are past it

    def test_a_reversal_starts_a_new_path(self) -> None:
        history, turns = self.drive([(1.0, 0.1)] * 20 + [(-1.0, 0.0)] * 5)
        assert history.sign == -1.0
        assert history.now[0] == pytest.approx(5.0)
        assert turns and all(t == pytest.approx(1.5, abs=0.15) for t in turns[-1:])  # before reversing

    def test_packing_round_trip(self) -> None:
        history, _ = self.drive([(1.0, 0.05)] * 12)
        back = TurnHistory.from_arrays(history.to_arrays())
        assert back.sign == history.sign
        assert np.array_equal(back.samples, history.samples)
        assert np.array_equal(back.now, history.now)
        assert TurnHistory.from_arrays(np.zeros(4)).samples.shape == (0, 2)

    def test_bad_parameters_name_the_field(self) -> None:
        with pytest.raises(BadInputError) as exc:
            replace(TURNS_DEFAULT, floor=0.0)
        assert exc.value.field == "floor"


def step(dx_m: float, dtheta_rad: float) -> OdometryStep:
    return OdometryStep(
        dx_m=dx_m,
        dtheta_rad=dtheta_rad,
        shift_px=(0.0, dx_m * 100),
        confidence=0.9,
        stationary=False,
        sigma_xy_m=0.01 + 0.03 * abs(dx_m),
        sigma_theta_rad=0.002,
        prev_T_curr=(dx_m, 0.0, dtheta_rad),
        model="linear",
    )


class TestLookAlikeBranches:
    """Two tunnels whose views are the same place for place: A straight, B turning left at 35 m. A vehicle
    drives B from a global start. Appearance alone keeps the belief split between the two; the corner it
    drove moves it to B."""

    @pytest.fixture(scope="class")
    @staticmethod
    def twins() -> tuple[np.ndarray, LocaliserMap]:
        tex = textures(N_BRANCH, seed=11)
        rng = np.random.default_rng(12)
        n = N_BRANCH
        thumbs = np.stack([view(tex[j % n], rng) for j in range(2 * n) for _ in range(FRAMES_PER_NODE)])
        straight_a = np.column_stack([np.arange(n) * SPACING_M, np.full(n, -200.0)])
        edges = np.r_[chain_edges(n), chain_edges(n, offset=n)]
        lmap = LocaliserMap(
            thumbs=thumbs,
            node_ptr=np.arange(0, FRAMES_PER_NODE * 2 * n + 1, FRAMES_PER_NODE, dtype=np.int64),
            centres_m=np.r_[straight_a, l_shape(y0_m=200.0)],
            adjacency_m=shortest_paths(2 * n, edges, np.full(edges.shape[0], SPACING_M), 50.0),
            max_adjacency_m=50.0,
            edges=edges,
        )
        return tex, lmap

    def belief_on_b(self, twins: tuple[np.ndarray, LocaliserMap], *, turns: bool) -> float:
        tex, lmap = twins
        params = replace(hmm.DEFAULT, lost_frames=0, relocate_ratio=0.0)  # keep both hypotheses
        kw = {} if turns else {"turn_params": None}
        loc = Localiser(lmap, params, **kw)
        rng = np.random.default_rng(13)
        corner_m = CORNER * SPACING_M
        turn_steps = round(4.0 / STEP_M)  # the body turns over the 4 m round the corner
        for k in range(int((N_BRANCH - 1) * SPACING_M / STEP_M)):
            s_m = k * STEP_M
            dtheta = QUARTER_RAD / turn_steps if corner_m - 2.0 <= s_m < corner_m + 2.0 else 0.0
            loc.step(view(tex[round(s_m / SPACING_M)], rng), k * 0.1, motion=step(STEP_M, dtheta))
        return float(loc.state().belief[N_BRANCH:].sum())

    def test_appearance_alone_cannot_tell(self, twins: tuple[np.ndarray, LocaliserMap]) -> None:
        assert 0.2 < self.belief_on_b(twins, turns=False) < 0.8

    def test_the_corner_driven_picks_the_branch(self, twins: tuple[np.ndarray, LocaliserMap]) -> None:
        assert self.belief_on_b(twins, turns=True) > 0.95
