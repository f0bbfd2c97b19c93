"""Putting dead-reckoned drives into the survey frame before the pose graph pins them.

A drive dead-reckoned from its odometry lives in its own frame, and a long one drifts in heading, so the
optimiser needs a start close to the answer: from far off, the robust kernel turns the true closures down
as outliers and Levenberg-Marquardt settles hundreds of metres wide of the map. :func:`initial_guess`
bends every drive with two or more groundings onto them stretch by stretch (:func:`bend_onto_points`),
moves drives reached only by loop closures by a consensus fit over those closures, translates drives with
one grounding, and then bridges the long stretches of a drive that run far from any grounding through
previously mapped tunnels (:func:`bridge_gaps`): there the closures to frames of other drives that are
themselves near a grounding say where the drive is, window by window, by consensus. It also names the gauge
anchors the graph needs (:class:`Anchor`): a weak prior on one pose of every group of drives that nothing
ties to the survey, and a weak heading prior where groundings fix the position but not the rotation.

Poses are (N, 3) float64 arrays of rows [x_m, y_m, yaw_rad] (``wTi``: frame i in the survey frame w).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.graph.alignment import (
    DEGENERATE_SPREAD_M,
    check_shape,
    compose,
    fit_rigid_robust,
    inverse,
    transform_poses,
    umeyama_2d,
    wrap_angle,
)
from driftmap.core.types import F64, I64

__all__ = ["Anchor", "bend_onto_points", "bridge_gaps", "initial_guess"]

REACH_M = 100.0  # a frame within this much travel of a grounding (or a bridged point) is trusted, metres
BRIDGE_WINDOW_M = 40.0  # travel per window whose closures agree on one bridging point, metres
BRIDGE_SUPPORT = 3  # closures that must agree on a bridging point
BRIDGE_PASSES = 3  # rounds over the drives (a bridged stretch can vouch for another drive's next round)


@dataclass(frozen=True)
class Anchor:
    """A weak prior fixing a gauge freedom of the graph.

    Attributes:
        chain: index of the drive.
        frame: index of the frame in that drive.
        wTi: (3,) pose the prior holds, survey frame, [x_m, y_m, yaw_rad].
        heading_only: only the yaw is held (position already fixed by groundings).
    """

    chain: int
    frame: int
    wTi: tuple[float, float, float]
    heading_only: bool


def _as_pose(row: F64) -> tuple[float, float, float]:
    return float(row[0]), float(row[1]), float(row[2])


def _components(num_chains: int, closure_chains: I64) -> list[list[int]]:
    parent = list(range(num_chains))

    def root(c: int) -> int:
        while parent[c] != c:
            parent[c] = parent[parent[c]]
            c = parent[c]
        return c

    for a, b in closure_chains:
        parent[root(int(a))] = root(int(b))
    groups: dict[int, list[int]] = {}
    for c in range(num_chains):
        groups.setdefault(root(c), []).append(c)
    return list(groups.values())


def bend_onto_points(wTi: F64, frames: I64, xy_m: F64, min_baseline_m: float) -> F64:
    """Bend a drive onto surveyed points of some of its frames, piece by piece between consecutive ones.

    A long drive's odometry drifts in heading, so one rigid fit leaves its groundings hundreds of metres
    off and its headings tens of degrees wrong: too far for the optimiser to pull back. Each stretch between
    two consecutive grounded frames is instead turned so that its chord points at the second grounding
    (when both chords span ``min_baseline_m``; else it turns like its neighbour), moved onto the first, and
    the distance it still misses at the second spread along it by travel. Frames before the first and after
    the last grounding follow the nearest stretch rigidly. Every grounded frame lands on its point. With a
    single point, or none far enough apart, the drive is moved by one rigid fit (:func:`umeyama_2d`).

    Args:
        wTi: (N, 3) poses of the drive, any frame.
        frames: (G,) frame indices of the points (groundings, or positions closures imply), any order
            (repeats averaged).
        xy_m: (G, 2) their positions in the survey frame, metres.
        min_baseline_m: shortest chord that sets a stretch's rotation, metres.

    Returns:
        (N, 3) poses in the survey frame.
    """
    poses = np.asarray(wTi, dtype=np.float64)
    at, where = np.unique(np.asarray(frames, dtype=np.int64), return_inverse=True)
    target = np.zeros((at.size, 2))
    np.add.at(target, where, np.asarray(xy_m, dtype=np.float64))
    target /= np.bincount(where, minlength=at.size)[:, None]
    chord_dr, chord_s = np.diff(poses[at, :2], axis=0), np.diff(target, axis=0)
    turn = wrap_angle(np.arctan2(chord_s[:, 1], chord_s[:, 0]) - np.arctan2(chord_dr[:, 1], chord_dr[:, 0]))
    known = (np.hypot(*chord_dr.T) >= min_baseline_m) & (np.hypot(*chord_s.T) >= min_baseline_m)
    if not known.any():  # one point, or none far enough apart to turn a stretch: one rigid fit
        R, t, _ = umeyama_2d(poses[at, :2], target)
        return transform_poses(poses, R, t)
    idx = np.arange(turn.size)
    nearest = np.flatnonzero(known)[np.abs(idx[:, None] - np.flatnonzero(known)[None, :]).argmin(axis=1)]
    turn = turn[nearest]
    travel = _travel(poses)
    out = np.empty_like(poses)
    for k in range(turn.size):  # stretch k: frames at[k] .. at[k + 1] (the first from 0, the last to the end)
        lo, hi = (0 if k == 0 else int(at[k])), (poses.shape[0] if k == turn.size - 1 else int(at[k + 1]) + 1)
        c, s_ = np.cos(turn[k]), np.sin(turn[k])
        R = np.array([[c, -s_], [s_, c]])
        piece = transform_poses(poses[lo:hi], R, target[k] - R @ poses[at[k], :2])
        miss = target[k + 1] - (R @ poses[at[k + 1], :2] + target[k] - R @ poses[at[k], :2])
        span = travel[at[k + 1]] - travel[at[k]]
        share = np.clip((travel[lo:hi] - travel[at[k]]) / span, 0.0, 1.0) if span > 0 else np.zeros(hi - lo)
        piece[:, :2] += share[:, None] * miss
        out[lo:hi] = piece
    return out


def _travel(poses: F64) -> F64:
    """(N,) distance driven up to each frame, metres."""
    return np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(poses[:, :2], axis=0).T))])


def _near(travel: F64, at_m: F64, reach_m: float) -> NDArray[np.bool_]:
    """(N,) whether each frame is within ``reach_m`` of travel of one of the positions ``at_m``."""
    if at_m.size == 0:
        return np.zeros(travel.size, dtype=bool)
    marks = np.sort(at_m)
    k = np.clip(np.searchsorted(marks, travel), 1, marks.size) - 1
    gap = np.minimum(np.abs(travel - marks[k]), np.abs(travel - marks[np.minimum(k + 1, marks.size - 1)]))
    return np.asarray(gap <= reach_m)


def _implied(
    c: int, poses: list[F64], trusted: list[NDArray[np.bool_]], closure_frames: I64, closure_aTb: F64
) -> tuple[I64, F64]:
    """Closures of drive ``c`` to trusted frames of other drives: (K,) own frames, (K, 3) implied poses
    (closures with ``c`` as their b side first, then as their a side, each in closure order)."""
    a_side = (closure_frames[:, 0] == c) & (closure_frames[:, 2] != c)
    b_side = (closure_frames[:, 2] == c) & (closure_frames[:, 0] != c)
    frames, implied = [], []
    for rows, own, other, flip in ((b_side, 3, 0, False), (a_side, 1, 2, True)):
        k = np.flatnonzero(rows)
        drive, frame = closure_frames[k, other], closure_frames[k, other + 1]
        ok, there = np.zeros(k.size, dtype=bool), np.zeros((k.size, 3))
        for d in np.unique(drive).tolist():
            at = drive == d
            ok[at], there[at] = trusted[d][frame[at]], poses[d][frame[at]]
        relative = inverse(closure_aTb[k[ok]]) if flip else closure_aTb[k[ok]]
        frames.append(closure_frames[k[ok], own])
        implied.append(compose(there[ok], relative))
    return np.concatenate(frames).astype(np.int64), np.concatenate(implied).reshape(-1, 3)


def _consensus_points(
    poses: F64, travel: F64, frames: I64, implied: F64, inlier_m: float
) -> tuple[list[int], list[F64]]:
    """One point per ``BRIDGE_WINDOW_M`` of travel where ``BRIDGE_SUPPORT`` closures agree within ``inlier_m``.

    Each closure moves the drive rigidly so its frame lands on the implied pose; the point is where those
    moves put the window's middle frame, averaged over the largest agreeing set.
    """
    out_frames: list[int] = []
    out_xy: list[F64] = []
    window = np.floor(travel[frames] / BRIDGE_WINDOW_M).astype(np.int64)
    for w in np.unique(window):
        members = np.flatnonzero(window == w)
        if members.size < BRIDGE_SUPPORT:
            continue
        middle = int(frames[members[np.argsort(frames[members])[members.size // 2]]])
        moves = compose(implied[members], inverse(poses[frames[members]]))  # (M, 3) survey-from-current
        there = compose(moves, np.broadcast_to(poses[middle], moves.shape))[:, :2]
        agree = np.linalg.norm(there[:, None, :] - there[None, :, :], axis=2) < inlier_m
        best = int(agree.sum(axis=1).argmax())
        if agree[best].sum() >= BRIDGE_SUPPORT:
            out_frames.append(middle)
            out_xy.append(there[agree[best]].mean(axis=0))
    return out_frames, out_xy


def bridge_gaps(
    poses: list[F64],
    fixed: list[bool],
    closure_frames: I64,
    closure_aTb: F64,
    grounding_frames: I64,
    grounding_xy_m: F64,
    inlier_m: float,
    min_baseline_m: float,
) -> list[F64]:
    """Bend the stretches of drives far from any grounding onto what their closures to trusted frames say.

    A frame is trusted when it lies within ``REACH_M`` of travel of a grounding of its drive (or of a point
    bridged earlier), or its drive is ``fixed``. For each drive, the closures from its untrusted frames to
    trusted frames of other drives give, window by window, a consensus point (:func:`_consensus_points`);
    the drive is bent again onto its groundings and those points (:func:`bend_onto_points`), and the frames
    near the points become trusted. Up to ``BRIDGE_PASSES`` rounds over the drives.

    Args:
        poses: per drive (N_c, 3) poses already placed in the survey frame.
        fixed: per drive, True to leave it as it is (poses given in the survey frame).
        closure_frames, closure_aTb, grounding_frames, grounding_xy_m: as for :func:`initial_guess`.
        inlier_m: agreement distance of the closures on a point, metres.
        min_baseline_m: see :func:`bend_onto_points`.

    Returns:
        Per drive (N_c, 3) poses.
    """
    poses = list(poses)
    travel = [_travel(p) for p in poses]
    trusted = []
    for c, p in enumerate(poses):
        own = grounding_frames[:, 0] == c
        trusted.append(
            np.ones(len(p), dtype=bool)
            if fixed[c]
            else _near(travel[c], travel[c][grounding_frames[own, 1]], REACH_M)
        )
    for _ in range(BRIDGE_PASSES):
        changed = False
        for c in range(len(poses)):
            if trusted[c].all():
                continue
            frames, implied = _implied(c, poses, trusted, closure_frames, closure_aTb)
            keep = ~trusted[c][frames]
            points, xy = _consensus_points(poses[c], travel[c], frames[keep], implied[keep], inlier_m)
            if not points:
                continue
            own = grounding_frames[:, 0] == c
            poses[c] = bend_onto_points(
                poses[c],
                np.concatenate([grounding_frames[own, 1], points]),
                np.concatenate([grounding_xy_m[own], np.asarray(xy)]),
                min_baseline_m,
            )
            trusted[c] |= _near(travel[c], travel[c][np.asarray(points)], REACH_M)
            changed = True
        if not changed:
            break
    return poses


def initial_guess(
    chain_wTi: list[F64],
    given: list[bool],
    closure_frames: I64,
    closure_aTb: F64,
    grounding_frames: I64,
    grounding_xy_m: F64,
    inlier_m: float,
    min_baseline_m: float = 5.0,
) -> tuple[list[F64], list[Anchor]]:
    """Place every drive in the survey frame and choose the gauge anchors.

    A drive whose groundings span at least ``min_baseline_m`` is bent onto them (:func:`warp_to_groundings`); one reached
    by closures from placed drives is moved by a consensus of those closures; one with groundings too close
    together to fix a rotation is only translated onto them; the rest keep their dead-reckoned pose.

    Args:
        chain_wTi: per drive c, (N_c, 3) dead-reckoned (or given) poses.
        given: per drive, True when its poses are already in the survey frame (kept as they are).
        closure_frames: (K, 4) int rows [chain_a, frame_a, chain_b, frame_b] of loop closures.
        closure_aTb: (K, 3) measured pose of frame b in frame a.
        grounding_frames: (G, 2) int rows [chain, frame] of groundings.
        grounding_xy_m: (G, 2) surveyed positions, survey frame, metres.
        inlier_m: agreement distance for placing drives by closures, metres.
        min_baseline_m: groundings closer together than this do not rotate a drive, metres.

    Returns:
        (poses, anchors): per drive (N_c, 3) initial poses in the survey frame, and the anchors.
    """
    check_shape("closure_frames", closure_frames, (None, 4))
    check_shape("closure_aTb", closure_aTb, (closure_frames.shape[0], 3))
    check_shape("grounding_frames", grounding_frames, (None, 2))
    check_shape("grounding_xy_m", grounding_xy_m, (grounding_frames.shape[0], 2))
    poses = [np.array(p, dtype=np.float64) for p in chain_wTi]
    placed = list(given)

    def rotation_fixed(rows: NDArray[np.bool_], baseline_m: float = DEGENERATE_SPREAD_M) -> bool:
        frames = {tuple(f) for f in grounding_frames[rows].tolist()}
        xy = grounding_xy_m[rows]
        return len(frames) >= 2 and float(np.linalg.norm(np.ptp(xy, axis=0))) > baseline_m

    for c in range(len(poses)):
        rows = grounding_frames[:, 0] == c
        if not placed[c] and rotation_fixed(rows, max(min_baseline_m, DEGENERATE_SPREAD_M)):
            poses[c] = bend_onto_points(
                poses[c], grounding_frames[rows, 1], grounding_xy_m[rows], min_baseline_m
            )
            placed[c] = True

    inter = closure_frames[:, 0] != closure_frames[:, 2]
    while not all(placed):
        progress = True
        while progress:  # spread placement along closures to drives already placed
            progress = False
            for c in range(len(poses)):
                if placed[c]:
                    continue
                done = np.array(placed, dtype=bool)
                fwd = inter & (closure_frames[:, 2] == c) & done[closure_frames[:, 0]]
                bwd = inter & (closure_frames[:, 0] == c) & done[closure_frames[:, 2]]
                if not fwd.any() and not bwd.any():
                    continue
                src = np.concatenate([poses[c][closure_frames[fwd, 3]], poses[c][closure_frames[bwd, 1]]])
                wTa = np.array([poses[a][i] for a, i in closure_frames[fwd, :2]]).reshape(-1, 3)
                wTb = np.array([poses[b][i] for b, i in closure_frames[bwd, 2:]]).reshape(-1, 3)
                dst = np.concatenate(
                    [compose(wTa, closure_aTb[fwd]), compose(wTb, inverse(closure_aTb[bwd]))]
                )
                R, t, _ = fit_rigid_robust(src, dst, inlier_m)
                poses[c], placed[c], progress = transform_poses(poses[c], R, t), True, True
        rest = [c for c in range(len(poses)) if not placed[c]]
        if not rest:
            break
        grounded = [c for c in rest if (grounding_frames[:, 0] == c).any()]
        c = grounded[0] if grounded else rest[0]
        rows = grounding_frames[:, 0] == c
        if grounded:  # one grounding, or several too close together to fix a rotation: translate
            t = grounding_xy_m[rows].mean(axis=0) - poses[c][grounding_frames[rows, 1], :2].mean(axis=0)
            poses[c] = transform_poses(poses[c], np.eye(2), t)
        placed[c] = True
    poses = bridge_gaps(
        poses,
        list(given),
        closure_frames,
        closure_aTb,
        grounding_frames,
        grounding_xy_m,
        inlier_m,
        min_baseline_m,
    )

    anchors = []
    for group in _components(len(poses), closure_frames[inter][:, [0, 2]]):
        rows = np.isin(grounding_frames[:, 0], group)
        if not rows.any():
            root = next((c for c in group if given[c]), group[0])
            anchors.append(Anchor(root, 0, _as_pose(poses[root][0]), False))
        elif not rotation_fixed(rows):
            c, i = (int(v) for v in grounding_frames[np.flatnonzero(rows)[0]])
            anchors.append(Anchor(c, i, _as_pose(poses[c][i]), True))
    return poses, anchors
