"""Placing drives before the pose graph: bending onto groundings, bridging long stretches by closures."""

from __future__ import annotations

import numpy as np

from driftmap.core.graph.alignment import dead_reckon
from driftmap.core.graph.constraints import GroundingConstraint, LoopConstraint, OdometryChain
from driftmap.core.graph.placement import bend_onto_points, bridge_gaps, initial_guess
from driftmap.core.graph.posegraph import optimise_pose_graph

STEP_M = 0.5


def tunnel(n: int) -> np.ndarray:
    """(n, 3) true steps of a winding tunnel, 0.5 m a step."""
    steps = np.zeros((n, 3))
    steps[:, 0] = STEP_M
    steps[:, 2] = 0.004 * np.sin(np.arange(n) / 150.0)
    return steps


def drifting(steps: np.ndarray, rate_rad_per_m: float) -> np.ndarray:
    """The steps as an odometry with a heading drift of ``rate_rad_per_m`` would measure them."""
    out = steps.copy()
    out[:, 2] += rate_rad_per_m * steps[:, 0]
    return out


def test_bending_lands_every_point_and_follows_a_drifting_drive() -> None:
    true_steps = tunnel(2000)  # 1 km
    truth = dead_reckon(true_steps, np.array([50.0, -20.0, 0.3]))
    dead = dead_reckon(drifting(true_steps, 0.002))  # 0.2 degrees a metre off: hundreds of metres by the end
    frames = np.arange(0, 2001, 100)
    rigid_error = np.abs(dead[:, :2] - truth[:, :2]).max()
    bent = bend_onto_points(dead, frames, truth[frames, :2], 5.0)
    np.testing.assert_allclose(bent[frames, :2], truth[frames, :2], atol=1e-9)
    assert rigid_error > 100.0
    assert np.linalg.norm(bent[:, :2] - truth[:, :2], axis=1).max() < 1.0


def test_too_short_stretches_turn_like_their_neighbours() -> None:
    dead = dead_reckon(tunnel(400))
    truth = dead.copy()
    frames = np.array([0, 2, 200, 400])  # 0 -> 2 spans 1 m: its turn is borrowed
    bent = bend_onto_points(dead, frames, truth[frames, :2], 5.0)
    np.testing.assert_allclose(bent[:, :2], truth[:, :2], atol=1e-6)


def two_drives_with_a_gap(
    false_closures: int = 0,
) -> tuple[list[np.ndarray], list[OdometryChain], list[LoopConstraint], list[GroundingConstraint]]:
    """Drive 0 grounded every 50 m along a 1.5 km tunnel; drive 1 along the same tunnel with a drifting
    odometry and groundings only in its first and last 150 m; closures 1 -> 0 every 2 m, some false."""
    true_steps = tunnel(3000)
    truth = dead_reckon(true_steps, np.array([1000.0, 500.0, 1.0]))
    sigmas = np.array([0.01, 0.01, 0.001])
    chains = [OdometryChain(true_steps, sigmas), OdometryChain(drifting(true_steps, 0.001), sigmas)]
    marks = [GroundingConstraint((0, int(f)), tuple(truth[f, :2]), 0.3) for f in range(0, 3001, 100)]
    marks += [
        GroundingConstraint((1, int(f)), tuple(truth[f, :2]), 0.3) for f in (0, 150, 300, 2700, 2850, 3000)
    ]
    closures = [LoopConstraint((0, f), (1, f), (2.0, 2.0, 0.1)) for f in range(0, 3001, 4)]
    rng = np.random.default_rng(5)
    for a, b in rng.integers(0, 3001, (false_closures, 2)):
        closures.append(LoopConstraint((0, int(a)), (1, int(b)), (2.0, 2.0, 0.1)))
    return [truth, truth], chains, closures, marks


def _guess(
    chains: list[OdometryChain], closures: list[LoopConstraint], marks: list[GroundingConstraint]
) -> list[np.ndarray]:
    closure_frames = np.array([(*c.a, *c.b) for c in closures], dtype=np.int64)
    grounding_frames = np.array([g.frame for g in marks], dtype=np.int64)
    grounding_xy = np.array([g.xy_m for g in marks])
    poses, _ = initial_guess(
        [dead_reckon(c.iTj) for c in chains], [False, False], closure_frames, np.zeros((len(closures), 3)),
        grounding_frames, grounding_xy, 5.0,
    )  # fmt: skip
    return poses


def test_a_long_ungrounded_stretch_is_bridged_by_its_closures() -> None:
    truth, chains, closures, marks = two_drives_with_a_gap(false_closures=40)
    poses = _guess(chains, closures, marks)
    gap = slice(400, 2600)
    assert np.linalg.norm(poses[1][gap, :2] - truth[1][gap, :2], axis=1).max() < 5.0
    result = optimise_pose_graph(chains, closures, marks)
    true_ones = np.arange(len(closures)) < 751
    assert result.closure_accepted[true_ones].mean() > 0.99
    assert not result.closure_accepted[~true_ones].any()
    assert np.linalg.norm(result.wTi[1][:, :2] - truth[1][:, :2], axis=1).max() < 1.0


def test_bridging_only_moves_frames_far_from_groundings() -> None:
    truth, chains, closures, marks = two_drives_with_a_gap()
    closure_frames = np.array([(*c.a, *c.b) for c in closures], dtype=np.int64)
    grounding_frames = np.array([g.frame for g in marks], dtype=np.int64)
    grounding_xy = np.array([g.xy_m for g in marks])
    placed = [bend_onto_points(dead_reckon(c.iTj), grounding_frames[grounding_frames[:, 0] == k, 1],
                               grounding_xy[grounding_frames[:, 0] == k], 5.0) for k, c in enumerate(chains)]  # fmt: skip
    bridged = bridge_gaps(
        placed, [False, False], closure_frames, np.zeros((len(closures), 3)), grounding_frames, grounding_xy,
        5.0, 5.0,
    )  # fmt: skip
    np.testing.assert_array_equal(bridged[0], placed[0])  # everywhere near a grounding
    far = slice(700, 2300)
    assert np.linalg.norm(placed[1][far, :2] - truth[1][far, :2], axis=1).min() > 10.0
    assert np.linalg.norm(bridged[1][far, :2] - truth[1][far, :2], axis=1).max() < 5.0


def test_points_too_close_together_move_the_drive_rigidly() -> None:
    out_and_back = np.zeros((200, 3))
    out_and_back[:, 0] = STEP_M
    out_and_back[99, 2] = np.pi  # turns round at 50 m
    dead = dead_reckon(out_and_back)
    bent = bend_onto_points(dead, np.array([0, 200]), np.array([[10.0, 20.0], [10.0, 21.0]]), 5.0)
    np.testing.assert_allclose(bent[:, :2] - bent[0, :2], dead[:, :2] - dead[0, :2], atol=1e-9)  # its shape
    np.testing.assert_allclose(bent[[0, 200], :2].mean(axis=0), [10.0, 20.5], atol=1e-9)
