"""Pose-graph back end: groundings, alignment, robust closures, incremental re-solves, clamping, M3500."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from driftmap.core.graph.alignment import dead_reckon, umeyama_2d
from driftmap.core.graph.constraints import (
    POSEGRAPH_DEFAULT,
    GroundingConstraint,
    LoopConstraint,
    OdometryChain,
    PoseGraphParams,
)
from driftmap.core.graph.placement import initial_guess
from driftmap.core.graph.posegraph import PoseGraphSession, optimise_pose_graph
from driftmap.errors import BadInputError
from tests.outside_data import SHARED_DATA

DATA = SHARED_DATA
POSE_TOL_M = 1e-6  # hand-computed optimum
WARM_TOL_M = 1e-4  # warm-started vs from-scratch solve
ATE_TARGET_M = 0.05  # M3500 + false closures vs the outlier-free solution (issue target)


def ate_m(wTi: np.ndarray, reference: np.ndarray) -> float:
    """RMS position error after a rigid alignment of ``wTi`` onto ``reference``, metres."""
    R, t, _ = umeyama_2d(wTi[:, :2], reference[:, :2])
    return float(np.sqrt(((wTi[:, :2] @ R.T + t - reference[:, :2]) ** 2).sum(axis=1).mean()))


def loop_world(seed: int = 3) -> tuple[np.ndarray, OdometryChain, list[LoopConstraint]]:
    """Two laps of a 20 m x 10 m rectangle in 1 m steps: truth (121, 3), noisy odometry, true closures."""
    side = [(1.0, 0.0, 0.0)] * 19 + [(1.0, 0.0, np.pi / 2)]
    short = [(1.0, 0.0, 0.0)] * 9 + [(1.0, 0.0, np.pi / 2)]
    steps = np.array((side + short) * 4)
    truth = dead_reckon(steps)
    rng = np.random.default_rng(seed)
    sigmas = np.array([0.02, 0.02, 0.005])
    chain = OdometryChain(steps + rng.normal(0.0, sigmas, steps.shape), sigmas)
    closures = [LoopConstraint((0, i), (0, i + 60), (0.05, 0.05, 0.02)) for i in range(0, 60, 3)]
    return truth, chain, closures


def grounded_at(truth: np.ndarray, frames: list[int], sigma_m: float = 0.1) -> list[GroundingConstraint]:
    return [GroundingConstraint((0, f), (float(truth[f, 0]), float(truth[f, 1])), sigma_m) for f in frames]


class TestGroundings:
    def test_one_grounding_moves_the_pair_onto_it(self) -> None:
        chain = OdometryChain(np.array([[1.0, 0.0, 0.0]]), np.array([0.1, 0.1, 0.01]))
        result = optimise_pose_graph([chain], [], [GroundingConstraint((0, 1), (5.0, 7.0), 0.5)])
        np.testing.assert_allclose(result.wTi[0], [[4.0, 7.0, 0.0], [5.0, 7.0, 0.0]], atol=POSE_TOL_M)
        np.testing.assert_allclose(result.grounding_residual_m, [[0.0, 0.0, 0.0]], atol=POSE_TOL_M)

    def test_two_groundings_share_the_disagreement_with_the_odometry(self) -> None:
        # 1-D least squares: 8 e^2 + 100 (0.2 + 2 e)^2 is least at e = -80 / 816.
        chain = OdometryChain(np.array([[1.0, 0.0, 0.0]]), np.array([0.1, 0.1, 0.01]))
        marks = [GroundingConstraint((0, 0), (0.0, 0.0), 0.5), GroundingConstraint((0, 1), (1.2, 0.0), 0.5)]
        result = optimise_pose_graph([chain], [], marks)
        e = 80.0 / 816.0
        np.testing.assert_allclose(result.wTi[0], [[e, 0.0, 0.0], [1.2 - e, 0.0, 0.0]], atol=POSE_TOL_M)
        np.testing.assert_allclose(result.grounding_residual_m, [[e, 0.0, e], [-e, 0.0, e]], atol=POSE_TOL_M)

    def test_residuals_are_optimised_minus_surveyed(self) -> None:
        truth, chain, closures = loop_world()
        marks = [GroundingConstraint((0, 0), (0.3, -0.2)), *grounded_at(truth, [20, 50, 95])]
        result = optimise_pose_graph([chain], closures, marks)
        for row, g in zip(result.grounding_residual_m, marks, strict=True):
            d = result.wTi[0][g.frame[1], :2] - np.array(g.xy_m)
            np.testing.assert_allclose(row, [d[0], d[1], np.hypot(*d)], atol=1e-12)
        assert result.grounding_ids == (0, 1, 2, 3)


class TestAlignment:
    def test_umeyama_recovers_a_similarity(self) -> None:
        rng = np.random.default_rng(0)
        src = rng.normal(0.0, 10.0, (30, 2))
        angle = 0.7
        R_true = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
        dst = 1.3 * src @ R_true.T + [500.0, -20.0]
        R, t, s = umeyama_2d(src, dst, with_scale=True)
        np.testing.assert_allclose(R, R_true, atol=1e-12)
        np.testing.assert_allclose(t, [500.0, -20.0], atol=1e-9)
        assert s == pytest.approx(1.3)
        _, _, s_rigid = umeyama_2d(src, dst)
        assert s_rigid == 1.0

    def test_straight_chain_is_turned_and_stretched_onto_its_end_groundings(self) -> None:
        chain = OdometryChain(np.tile([1.0, 0.0, 0.0], (10, 1)), np.array([0.5, 0.05, 0.01]))
        marks = [
            GroundingConstraint((0, 0), (100.0, 200.0), 0.01),
            GroundingConstraint((0, 10), (100.0, 212.0), 0.01),
        ]
        frames = np.array([g.frame for g in marks])
        xy = np.array([g.xy_m for g in marks])
        (guess,), anchors = initial_guess(
            [dead_reckon(chain.iTj)], [False], np.zeros((0, 4), np.int64), np.zeros((0, 3)), frames, xy, 5.0
        )
        np.testing.assert_allclose(guess[:, 0], 100.0, atol=1e-9)  # turned, and the 2 m it misses spread
        np.testing.assert_allclose(guess[:, 1], 200.0 + 1.2 * np.arange(11), atol=1e-9)
        np.testing.assert_allclose(guess[:, 2], np.pi / 2, atol=1e-12)
        assert anchors == []
        result = optimise_pose_graph([chain], [], marks)
        np.testing.assert_allclose(result.wTi[0][:, 0], 100.0, atol=1e-6)
        np.testing.assert_allclose(result.wTi[0][:, 1], 200.0 + 1.2 * np.arange(11), atol=1e-3)
        np.testing.assert_allclose(result.wTi[0][:, 2], np.pi / 2, atol=1e-6)

    def test_groundings_close_together_only_translate(self) -> None:
        dead = dead_reckon(np.tile([1.0, 0.0, 0.0], (100, 1)))  # 100 m along x
        frames = np.array([[0, 0], [0, 1]])
        xy = np.array([[10.0, 20.0], [10.5, 20.9]])  # 1 m apart, 60 degrees off: too short to trust
        none = (np.zeros((0, 4), np.int64), np.zeros((0, 3)))
        (guess,), anchors = initial_guess([dead], [False], *none, frames, xy, 5.0, min_baseline_m=5.0)
        np.testing.assert_allclose(guess[:, 2], 0.0)
        np.testing.assert_allclose(guess[:2, :2].mean(axis=0), xy.mean(axis=0), atol=1e-12)
        assert anchors == []  # the optimiser still gets the rotation from both groundings

    def test_ungrounded_drive_is_placed_by_its_closures(self) -> None:
        truth, chain, closures = loop_world()
        # a second drive over the first lap, dead-reckoned from its own origin, joined by closures only
        second = OdometryChain(chain.iTj[:60], chain.sigmas)
        joins = [LoopConstraint((0, i), (1, i), (0.05, 0.05, 0.02)) for i in range(0, 60, 5)]
        joins.append(LoopConstraint((0, 10), (1, 45), (0.05, 0.05, 0.02)))  # a wrong one
        marks = grounded_at(truth, [0, 20, 90])
        result = optimise_pose_graph([chain, second], closures + joins, marks)
        assert ate_m(result.wTi[1], truth[:61]) < 0.3
        assert np.abs(result.wTi[1][:, :2] - truth[:61, :2]).max() < 1.0

    def test_drive_without_groundings_or_closures_stays_dead_reckoned(self) -> None:
        truth, chain, closures = loop_world()
        lone = OdometryChain(np.tile([0.5, 0.0, 0.01], (20, 1)), np.array([0.05, 0.05, 0.01]))
        result = optimise_pose_graph([chain, lone], closures, grounded_at(truth, [0, 20]))
        np.testing.assert_allclose(result.wTi[1], dead_reckon(lone.iTj), atol=1e-6)


World = tuple[np.ndarray, OdometryChain, list[LoopConstraint], list[GroundingConstraint]]


@pytest.fixture(scope="module")
def world() -> World:
    """The loop world grounded at three frames."""
    truth, chain, closures = loop_world()
    return truth, chain, closures, grounded_at(truth, [0, 20, 90])


class TestRobustClosures:
    FALSE = (
        LoopConstraint((0, 10), (0, 45), (0.05, 0.05, 0.02)),
        LoopConstraint((0, 70), (0, 105), (0.05, 0.05, 0.02)),
    )

    def test_plain_least_squares_is_bent_by_a_false_closure(self, world: World) -> None:
        _, chain, closures, marks = world
        params = PoseGraphParams(loop_kernel="none")
        clean = optimise_pose_graph([chain], closures, marks, params).wTi[0]
        bent = optimise_pose_graph([chain], [*closures, *self.FALSE], marks, params).wTi[0]
        assert np.abs(bent[:, :2] - clean[:, :2]).max() > 1.0

    @pytest.mark.parametrize("kernel", ["dcs", "geman_mcclure", "gnc_tls"])
    def test_robust_kernel_ignores_a_false_closure(self, world: World, kernel: str) -> None:
        truth, chain, closures, marks = world
        params = PoseGraphParams(loop_kernel=kernel)  # type: ignore[arg-type]
        clean = optimise_pose_graph([chain], closures, marks, params)
        result = optimise_pose_graph([chain], [*closures, *self.FALSE], marks, params)
        assert np.abs(result.wTi[0][:, :2] - clean.wTi[0][:, :2]).max() < 0.01
        assert ate_m(result.wTi[0], truth) < 0.2
        assert result.closure_accepted[: len(closures)].all()
        assert not result.closure_accepted[len(closures) :].any()
        assert (result.closure_weight[len(closures) :] < 0.01).all()

    def test_isam2_solver_reaches_the_batch_optimum(self, world: World) -> None:
        _, chain, closures, marks = world
        batch = optimise_pose_graph([chain], closures, marks)
        incremental = optimise_pose_graph([chain], closures, marks, PoseGraphParams(solver="isam2"))
        np.testing.assert_allclose(incremental.wTi[0], batch.wTi[0], atol=1e-4)
        assert incremental.final_error == pytest.approx(batch.final_error, rel=1e-6)


class TestIncremental:
    def test_grounding_edits_warm_start_to_the_from_scratch_optimum(self) -> None:
        truth, chain, closures = loop_world()
        session = PoseGraphSession([chain], closures, grounded_at(truth, [0, 20]))
        first = session.solve()
        assert first.iterations > 0
        moved = session.add_grounding(
            GroundingConstraint((0, 90), (float(truth[90, 0]) + 0.4, float(truth[90, 1])), 0.1)
        )
        session.solve()
        session.move_grounding(moved, (float(truth[90, 0]), float(truth[90, 1]) - 0.3), 0.2)
        session.remove_grounding(0)
        session.add_grounding(GroundingConstraint((0, 40), (float(truth[40, 0]), float(truth[40, 1]))))
        warm = session.solve()
        scratch = optimise_pose_graph([chain], closures, list(session.groundings.values()))
        np.testing.assert_allclose(warm.wTi[0][:, :2], scratch.wTi[0][:, :2], atol=WARM_TOL_M)
        np.testing.assert_allclose(warm.grounding_residual_m, scratch.grounding_residual_m, atol=WARM_TOL_M)
        assert warm.grounding_ids == (1, 2, 3)
        assert warm.final_error == pytest.approx(scratch.final_error, rel=1e-6)

    def test_first_grounding_of_a_floating_map_restarts_from_the_alignment(self) -> None:
        truth, chain, closures = loop_world()
        session = PoseGraphSession([chain], closures)
        floating = session.solve()
        np.testing.assert_allclose(floating.wTi[0][0], [0.0, 0.0, 0.0], atol=1e-2)  # anchored where it began
        for g in grounded_at(truth, [0, 20]):
            session.add_grounding(dataclasses.replace(g, xy_m=(g.xy_m[0] + 1000.0, g.xy_m[1] - 500.0)))
        warm = session.solve()
        scratch = optimise_pose_graph([chain], closures, list(session.groundings.values()))
        np.testing.assert_allclose(warm.wTi[0], scratch.wTi[0], atol=WARM_TOL_M)
        assert warm.wTi[0][0, 0] == pytest.approx(1000.0, abs=0.5)

    def test_a_graph_warm_started_from_an_earlier_solution_reaches_the_cold_optimum_sooner(self) -> None:
        truth, chain, closures = loop_world()
        earlier = optimise_pose_graph([chain], closures, grounded_at(truth, [0, 20]))
        groundings = grounded_at(truth, [0, 20, 90])  # a grounding added since
        cold = optimise_pose_graph([chain], closures, groundings)
        warm = optimise_pose_graph([chain], closures, groundings, warm=[earlier.wTi[0]])
        np.testing.assert_allclose(warm.wTi[0][:, :2], cold.wTi[0][:, :2], atol=WARM_TOL_M)
        assert warm.final_error == pytest.approx(cold.final_error, rel=1e-6)
        assert 0 < warm.iterations < cold.iterations
        with pytest.raises(BadInputError, match=r"warm\[0\]"):
            optimise_pose_graph([chain], closures, groundings, warm=[earlier.wTi[0][:-1]])


class TestClamping:
    def test_tiny_sigmas_are_clamped_to_the_floor(self) -> None:
        steps = np.array([[1.0, 0.0, 0.0], [1.0, 0.0, 0.1]])
        marks = [GroundingConstraint((0, 0), (0.0, 0.0), 1e-9), GroundingConstraint((0, 2), (2.5, 0.0), 1e-9)]
        floor = POSEGRAPH_DEFAULT
        tiny = OdometryChain(steps, np.full(3, 1e-12))
        at_floor = OdometryChain(steps, np.array([floor.min_sigma_m, floor.min_sigma_m, floor.min_sigma_rad]))
        information = OdometryChain(
            steps, np.ones(3), information=np.tile(np.diag([1e24, 1e24, 1e24]), (2, 1, 1))
        )
        clamped_marks = [dataclasses.replace(g, sigma_m=floor.min_sigma_m) for g in marks]
        expected = optimise_pose_graph([at_floor], [], clamped_marks)
        assert expected.iterations > 0 and expected.final_error < expected.initial_error
        for chain in (tiny, information):
            result = optimise_pose_graph([chain], [], marks)
            np.testing.assert_allclose(result.wTi[0], expected.wTi[0], atol=1e-9)

    def test_bad_inputs_name_the_field(self) -> None:
        chain = OdometryChain(np.zeros((3, 3)), np.array([0.1, 0.1, 0.01]))
        cases = [
            ([OdometryChain(np.zeros((3, 3)), np.array([0.1, -1.0, 0.01]))], [], [], "chains[0].sigmas"),
            ([chain], [LoopConstraint((0, 1), (0, 9), (0.1, 0.1, 0.1))], [], "closures[0].b"),
            (
                [chain],
                [
                    LoopConstraint((0, 1), (0, 2), (0.1, 0.1, 0.1)),
                    LoopConstraint((5, 1), (0, 2), (0.1, 0.1, 0.1)),
                ],
                [],
                "closures[1].a",
            ),
            ([chain], [LoopConstraint((0, 1), (0, 2), (0.1, 0.0, 0.1))], [], "closures[0].sigmas"),
            ([chain], [LoopConstraint((0, 1, 2), (0, 2), (0.1, 0.1, 0.1))], [], "closures[0].a"),  # type: ignore[arg-type]
            ([chain], [LoopConstraint((0, 1), (0, 1.5), (0.1, 0.1, 0.1))], [], "closures[0].b"),  # type: ignore[arg-type]
            (
                [chain],
                [LoopConstraint((0, 1), (0, 2), (0.1, 0.1, 0.1), information=-np.eye(3))],
                [],
                "closures[0].information",
            ),
            ([chain], [], [GroundingConstraint((1, 0), (0.0, 0.0))], "groundings[0].frame"),
            ([chain], [], [GroundingConstraint((0, 0), (0.0, float("nan")))], "groundings[0]"),
        ]
        for chains, closures, marks, field in cases:
            with pytest.raises(BadInputError) as caught:
                optimise_pose_graph(chains, closures, marks)
            assert caught.value.field == field
        with pytest.raises(ValueError):
            PoseGraphParams(loop_kernel="tukey")  # type: ignore[arg-type]


def false_closures(
    num_poses: int, count: int, information: np.ndarray, seed: int
) -> list[tuple[int, int, np.ndarray, np.ndarray]]:
    """False closures by the protocol of ``posegraphs/README.md``: (i, j, [x, y, theta], information).

    Both ends uniform and not neighbours, x, y ~ N(0, 0.3 m), theta ~ N(0, 10 deg), a true closure's information.
    """
    rng = np.random.default_rng(seed)
    out: list[tuple[int, int, np.ndarray, np.ndarray]] = []
    while len(out) < count:
        i, j = (int(v) for v in rng.integers(0, num_poses, 2))
        if abs(i - j) > 1:
            measured = np.array([rng.normal(0, 0.3), rng.normal(0, 0.3), rng.normal(0, np.deg2rad(10.0))])
            out.append((i, j, measured, information[rng.integers(len(information))]))
    return out


@pytest.mark.skipif(not (DATA / "posegraphs" / "M3500_olson.g2o").exists(), reason="shared/data is absent")
def test_m3500_with_20_percent_false_closures_keeps_the_clean_map() -> None:
    from driftmap.formats.g2o import read_g2o, to_pose_graph

    chains, closures = to_pose_graph(read_g2o(DATA / "posegraphs" / "M3500_olson.g2o"))
    assert len(chains) == 1 and len(closures) == 2099
    clean = optimise_pose_graph(chains, closures, (), PoseGraphParams(loop_kernel="none")).all_poses()
    infos = np.array([c.information for c in closures])
    wrong = [
        LoopConstraint((0, i), (0, j), (1.0, 1.0, 1.0), (m[0], m[1], m[2]), information=info)
        for i, j, m, info in false_closures(len(clean), round(0.2 * len(closures)), infos, seed=0)
    ]
    result = optimise_pose_graph(chains, closures + wrong, (), POSEGRAPH_DEFAULT)
    assert ate_m(result.all_poses(), clean) <= ATE_TARGET_M


@pytest.mark.skipif(not (DATA / "posegraphs" / "MITb.g2o").exists(), reason="shared/data is absent")
def test_an_indeterminate_system_for_the_dog_leg_is_solved_by_levenberg_marquardt(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """MIT Killian's plain least-squares graph is too poorly conditioned for the undamped dog leg."""
    import gtsam

    from driftmap.core.graph import posegraph
    from driftmap.formats.g2o import read_g2o, to_pose_graph

    raised: list[str] = []
    real_dogleg = gtsam.DoglegOptimizer

    class Watched:  # the real dog leg, its failure noted
        def __init__(self, *args: object) -> None:
            self._real = real_dogleg(*args)

        def optimize(self) -> gtsam.Values:
            try:
                return self._real.optimize()
            except RuntimeError as error:
                raised.append(str(error))
                raise

        def iterations(self) -> int:
            return int(self._real.iterations())

    monkeypatch.setattr(posegraph.gtsam, "DoglegOptimizer", Watched)
    chains, closures = to_pose_graph(read_g2o(DATA / "posegraphs" / "MITb.g2o"))
    plain = PoseGraphParams(loop_kernel="none", solver="dogleg")
    fallback = optimise_pose_graph(chains, closures, (), plain)
    assert len(raised) == 1 and "Indeterminate" in raised[0]
    lm = optimise_pose_graph(chains, closures, (), dataclasses.replace(plain, solver="lm"))
    assert fallback.final_error == pytest.approx(lm.final_error, rel=1e-9)
    np.testing.assert_allclose(fallback.all_poses(), lm.all_poses(), atol=1e-9)


@pytest.mark.skipif(not (DATA / "posegraphs" / "city10000.g2o").exists(), reason="shared/data is absent")
def test_levenberg_marquardt_stopped_short_is_continued_by_the_dog_leg() -> None:
    """The default solver is LM's solution when LM converges, and LM then the dog leg when LM runs out."""
    from driftmap.formats.g2o import read_g2o, to_pose_graph

    chains, closures = to_pose_graph(read_g2o(DATA / "posegraphs" / "city10000.g2o"))
    plain = PoseGraphParams(loop_kernel="none")
    assert plain.solver == "lm_dogleg"
    converged = optimise_pose_graph(chains, closures, (), plain)
    lm = optimise_pose_graph(chains, closures, (), dataclasses.replace(plain, solver="lm"))
    assert converged.iterations == lm.iterations < plain.max_iterations
    np.testing.assert_array_equal(converged.all_poses(), lm.all_poses())
    capped = dataclasses.replace(plain, max_iterations=3)  # LM needs 6 on this graph
    lm_short = optimise_pose_graph(chains, closures, (), dataclasses.replace(capped, solver="lm"))
    continued = optimise_pose_graph(chains, closures, (), capped)
    assert lm_short.iterations == 3 and continued.iterations == 6  # three of LM, three of the dog leg
    assert continued.final_error < 0.5 * lm_short.final_error
