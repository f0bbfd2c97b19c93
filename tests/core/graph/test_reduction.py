"""The keyframe-level pose graph: odometry composed between nodes, frames expanded back, same optimum."""

from __future__ import annotations

import dataclasses

import gtsam
import numpy as np

from driftmap.core.graph.alignment import dead_reckon
from driftmap.core.graph.constraints import (
    POSEGRAPH_DEFAULT,
    GroundingConstraint,
    LoopConstraint,
    OdometryChain,
)
from driftmap.core.graph.posegraph import PoseGraphSession, optimise_pose_graph
from driftmap.core.graph.reduction import compose_segments, expand_chain, node_frames

EVERY_FRAME = dataclasses.replace(POSEGRAPH_DEFAULT, node_spacing_m=0.0)
SAME_OPTIMUM_M = 0.01  # keyframe-level vs frame-level solution, every frame


def curvy_steps(n: int, seed: int = 0) -> np.ndarray:
    """(n, 3) steps of 0.4 m forward with slowly varying turns, and some standing still."""
    rng = np.random.default_rng(seed)
    steps = np.zeros((n, 3))
    steps[:, 0] = 0.4
    steps[:, 2] = 0.03 * np.sin(np.arange(n) / 40.0) + rng.normal(0.0, 0.002, n)
    steps[n // 3 : n // 3 + 80] = 0.0  # the vehicle waits
    return steps


def two_laps(
    seed: int = 1,
) -> tuple[np.ndarray, OdometryChain, list[LoopConstraint], list[GroundingConstraint]]:
    """Two laps of a 40 m x 20 m rectangle in 0.4 m steps, noisy odometry, closures lap to lap, 3 groundings."""
    lap = ([(0.4, 0.0, 0.0)] * 99 + [(0.4, 0.0, np.pi / 2)]) + (
        [(0.4, 0.0, 0.0)] * 49 + [(0.4, 0.0, np.pi / 2)]
    )
    steps = np.array(lap * 4)
    truth = dead_reckon(steps)
    rng = np.random.default_rng(seed)
    sigmas = np.array([0.01, 0.01, 0.002])
    chain = OdometryChain(steps + rng.normal(0.0, sigmas, steps.shape), sigmas)
    period = len(lap) * 2
    closures = [LoopConstraint((0, i), (0, i + period), (0.05, 0.05, 0.02)) for i in range(7, period, 23)]
    marks = [
        GroundingConstraint((0, f), (float(truth[f, 0]), float(truth[f, 1])), 0.1) for f in (0, 130, 420)
    ]
    return truth, chain, closures, marks


def test_nodes_keep_the_ends_the_required_frames_and_a_node_per_spacing() -> None:
    steps = curvy_steps(400)
    nodes = node_frames(steps, np.array([17, 17, 250]), spacing_m=5.0, max_steps=30)
    assert nodes[0] == 0 and nodes[-1] == 400 and {17, 250} <= set(nodes.tolist())
    assert np.all(np.diff(nodes) > 0) and np.diff(nodes).max() <= 30
    travel = np.cumsum(np.r_[0.0, np.hypot(steps[:, 0], steps[:, 1])])
    assert np.diff(travel[nodes]).max() < 5.0 + 0.4 + 1e-9
    np.testing.assert_array_equal(node_frames(steps, np.array([], dtype=np.int64), 0.0, 30), np.arange(401))


def test_composed_covariance_is_gtsams_marginal_of_the_segment() -> None:
    steps = curvy_steps(25, seed=2)[:25]
    rng = np.random.default_rng(3)
    A = rng.normal(0.0, 1.0, (25, 3, 3)) * np.array([0.01, 0.01, 0.002])[:, None]
    covariance = A @ A.transpose(0, 2, 1) + np.diag([1e-4, 1e-4, 1e-6])
    composed, cov = compose_segments(steps, covariance, np.array([0, 25]))
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    graph.add(gtsam.PriorFactorPose2(0, gtsam.Pose2(), gtsam.noiseModel.Isotropic.Sigma(3, 1e-9)))
    for i, pose in enumerate(dead_reckon(steps)):
        values.insert(i, gtsam.Pose2(*pose))
    for i in range(25):
        model = gtsam.noiseModel.Gaussian.Covariance(covariance[i])
        graph.add(gtsam.BetweenFactorPose2(i, i + 1, gtsam.Pose2(*steps[i]), model))
    np.testing.assert_allclose(composed[0], dead_reckon(steps)[-1], atol=1e-12)
    np.testing.assert_allclose(
        cov[0], gtsam.Marginals(graph, values).marginalCovariance(25), rtol=1e-6, atol=1e-15
    )


def test_expanding_dead_reckoned_nodes_gives_the_dead_reckoning() -> None:
    steps = curvy_steps(300)
    covariance = np.tile(np.diag([1e-4, 1e-4, 1e-6]), (300, 1, 1))
    poses = dead_reckon(steps, np.array([3.0, -2.0, 1.0]))
    nodes = node_frames(steps, np.array([120]), 5.0, 40)
    expanded = expand_chain(poses[nodes], nodes, steps, covariance)
    np.testing.assert_allclose(expanded[:, :2], poses[:, :2], atol=1e-9)
    np.testing.assert_allclose(np.cos(expanded[:, 2] - poses[:, 2]), 1.0, atol=1e-12)


def test_expanding_keeps_the_nodes_and_spreads_the_gap_smoothly() -> None:
    steps = curvy_steps(100)
    covariance = np.tile(np.diag([1e-4, 1e-4, 1e-6]), (100, 1, 1))
    nodes = np.array([0, 50, 100])
    solved = dead_reckon(steps)[nodes] + np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.01], [0.0, 0.1, -0.02]])
    expanded = expand_chain(solved, nodes, steps, covariance)
    np.testing.assert_allclose(expanded[nodes], solved, atol=1e-12)
    jumps = np.linalg.norm(np.diff(expanded[:, :2], axis=0), axis=1)
    assert np.all(np.abs(jumps - np.hypot(steps[:, 0], steps[:, 1])) < 0.02)  # no frame jumps


def test_the_keyframe_graph_reaches_the_frame_graphs_optimum() -> None:
    _truth, chain, closures, marks = two_laps()
    full = optimise_pose_graph([chain], closures, marks, EVERY_FRAME)
    reduced = optimise_pose_graph([chain], closures, marks)
    assert np.abs(full.wTi[0][:, :2] - reduced.wTi[0][:, :2]).max() < SAME_OPTIMUM_M
    np.testing.assert_array_equal(full.closure_accepted, reduced.closure_accepted)
    np.testing.assert_allclose(full.grounding_residual_m, reduced.grounding_residual_m, atol=SAME_OPTIMUM_M)


def test_a_grounding_added_between_nodes_becomes_a_node() -> None:
    truth, chain, closures, marks = two_laps()
    session = PoseGraphSession([chain], closures, marks)
    session.solve()
    gid = session.add_grounding(
        GroundingConstraint((0, 311), (float(truth[311, 0]) + 2.0, float(truth[311, 1])), 0.01)
    )
    moved = session.solve()
    assert abs(moved.grounding_residual_m[list(moved.grounding_ids).index(gid), 2]) < 0.05
    full = optimise_pose_graph([chain], closures, list(session.groundings.values()), EVERY_FRAME)
    assert np.abs(full.wTi[0][:, :2] - moved.wTi[0][:, :2]).max() < SAME_OPTIMUM_M
