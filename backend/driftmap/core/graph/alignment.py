"""Global alignment of dead-reckoned drives to the survey frame, before the pose graph pins them.

Poses are (N, 3) float64 arrays of rows [x_m, y_m, yaw_rad]; ``wTi`` is frame i in the survey (world)
frame w, ``iTj`` is frame j in frame i. A drive dead-reckoned from its odometry lives in its own frame;
:func:`initial_guess` moves every drive rigidly into the survey frame, so the optimiser starts from a map
that is not sheared towards the first grounding: drives with two or more groundings by a 2-D Procrustes
fit (:func:`umeyama_2d`), drives reached by loop closures by a consensus fit over those closures
(:func:`fit_rigid_robust`), drives with one grounding by a translation. It also names the gauge anchors the
graph needs (:class:`Anchor`): a weak prior on one pose of every group of drives that nothing ties to the
survey, and a weak heading prior where groundings fix the position but not the rotation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.types import F64, I64

_DEGENERATE_SPREAD_M = 1e-3  # points closer together than this fix no rotation


def _check(name: str, array: NDArray, shape: tuple[int | None, ...]) -> None:
    if array.ndim != len(shape) or any(
        s is not None and s != n for s, n in zip(shape, array.shape, strict=True)
    ):
        raise ValueError(f"{name} must have shape {shape}, got {array.shape}")


def wrap_angle(angle_rad: F64) -> F64:
    """Wrap angles to [-pi, pi), any shape, radians."""
    return np.asarray((angle_rad + np.pi) % (2.0 * np.pi) - np.pi, dtype=np.float64)


def compose(aTb: F64, bTc: F64) -> F64:
    """Compose SE(2) poses row by row: aTc = aTb * bTc; both (K, 3) or (3,), [x_m, y_m, yaw_rad]."""
    a, b = np.asarray(aTb, dtype=np.float64), np.asarray(bTc, dtype=np.float64)
    cos, sin = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + cos * b[..., 0] - sin * b[..., 1]
    y = a[..., 1] + sin * b[..., 0] + cos * b[..., 1]
    return np.stack([x, y, wrap_angle(a[..., 2] + b[..., 2])], axis=-1)


def inverse(aTb: F64) -> F64:
    """Invert SE(2) poses row by row: bTa from aTb, (K, 3) or (3,)."""
    a = np.asarray(aTb, dtype=np.float64)
    cos, sin = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -(cos * a[..., 0] + sin * a[..., 1])
    y = -(-sin * a[..., 0] + cos * a[..., 1])
    return np.stack([x, y, wrap_angle(-a[..., 2])], axis=-1)


def dead_reckon(iTj: F64, wT0: F64 | None = None) -> F64:
    """Chain relative steps into absolute poses.

    Args:
        iTj: (N-1, 3) step i -> i+1, frame i+1 in frame i, [dx_m, dy_m, dtheta_rad].
        wT0: (3,) pose of the first frame; identity when None.

    Returns:
        (N, 3) poses wTi of every frame.
    """
    steps = np.asarray(iTj, dtype=np.float64)
    _check("iTj", steps, (None, 3))
    start = np.zeros(3) if wT0 is None else np.asarray(wT0, dtype=np.float64)
    yaw = start[2] + np.concatenate([[0.0], np.cumsum(steps[:, 2])])
    cos, sin = np.cos(yaw[:-1]), np.sin(yaw[:-1])
    dx = cos * steps[:, 0] - sin * steps[:, 1]
    dy = sin * steps[:, 0] + cos * steps[:, 1]
    x = start[0] + np.concatenate([[0.0], np.cumsum(dx)])
    y = start[1] + np.concatenate([[0.0], np.cumsum(dy)])
    return np.stack([x, y, wrap_angle(yaw)], axis=1)


def transform_poses(wTi: F64, R: F64, t: F64) -> F64:
    """Move poses rigidly: positions p -> R p + t, yaw -> yaw + angle(R). wTi (N, 3), R (2, 2), t (2,)."""
    poses = np.asarray(wTi, dtype=np.float64)
    xy = poses[:, :2] @ np.asarray(R).T + np.asarray(t)
    return np.column_stack([xy, wrap_angle(poses[:, 2] + np.arctan2(R[1, 0], R[0, 0]))])


def umeyama_2d(src: F64, dst: F64, with_scale: bool = False) -> tuple[F64, F64, float]:
    """Least-squares similarity (or rigid) transform taking points ``src`` onto ``dst`` (Umeyama 1991).

    Args:
        src: (N, 2) points, N >= 1, metres, any frame a.
        dst: (N, 2) corresponding points, metres, frame b.
        with_scale: also fit a scale; otherwise s = 1 (rigid).

    Returns:
        (R, t, s): (2, 2) rotation, (2,) translation in metres and scale with dst ~= s * R @ src + t.
        With fewer than two distinct source points the rotation is the identity (a translation fit).
    """
    a, b = np.asarray(src, dtype=np.float64), np.asarray(dst, dtype=np.float64)
    _check("src", a, (None, 2))
    _check("dst", b, (a.shape[0], 2))
    if a.shape[0] == 0:
        raise ValueError("umeyama_2d needs at least one point")
    mu_a, mu_b = a.mean(axis=0), b.mean(axis=0)
    da, db = a - mu_a, b - mu_b
    var_a = float((da**2).sum()) / a.shape[0]
    if np.sqrt(var_a) < _DEGENERATE_SPREAD_M:
        return np.eye(2), mu_b - mu_a, 1.0
    U, S, Vt = np.linalg.svd(db.T @ da / a.shape[0])
    D = np.diag([1.0, np.sign(np.linalg.det(U @ Vt)) or 1.0])
    R = U @ D @ Vt
    s = float(np.trace(np.diag(S) @ D)) / var_a if with_scale else 1.0
    return R, mu_b - s * R @ mu_a, s


def fit_rigid_robust(
    src_poses: F64, dst_poses: F64, inlier_m: float, max_hypotheses: int = 64
) -> tuple[F64, F64, NDArray[np.bool_]]:
    """Rigid transform taking ``src_poses`` onto ``dst_poses`` by consensus, ignoring wrong pairs.

    Every pair proposes the transform dst * inv(src); the proposal under which most pairs' positions agree
    within ``inlier_m`` wins (ties: smaller summed distance) and is refined by :func:`umeyama_2d` on its
    inliers when they are spread out.

    Args:
        src_poses: (K, 3) poses in the frame being moved, K >= 1.
        dst_poses: (K, 3) the same frames' poses in the target frame.
        inlier_m: distance under which a pair agrees with a proposal, metres.
        max_hypotheses: at most this many evenly spaced pairs propose.

    Returns:
        (R (2, 2), t (2,), inliers (K,) bool) with dst ~= R @ src + t.
    """
    src, dst = np.asarray(src_poses, dtype=np.float64), np.asarray(dst_poses, dtype=np.float64)
    _check("src_poses", src, (None, 3))
    _check("dst_poses", dst, (src.shape[0], 3))
    picks = np.unique(np.linspace(0, src.shape[0] - 1, min(src.shape[0], max_hypotheses)).astype(np.int64))
    proposals = compose(dst[picks], inverse(src[picks]))  # (H, 3) target-from-source
    cos, sin = np.cos(proposals[:, 2])[:, None], np.sin(proposals[:, 2])[:, None]
    px = cos * src[None, :, 0] - sin * src[None, :, 1] + proposals[:, 0:1]
    py = sin * src[None, :, 0] + cos * src[None, :, 1] + proposals[:, 1:2]
    dist = np.hypot(px - dst[None, :, 0], py - dst[None, :, 1])  # (H, K)
    inliers_all = dist < inlier_m
    counts = inliers_all.sum(axis=1)
    cost = np.where(inliers_all, dist, inlier_m).sum(axis=1)
    best = int(np.lexsort((cost, -counts))[0])
    inliers = inliers_all[best]
    R, t, _ = umeyama_2d(src[inliers, :2], dst[inliers, :2])
    if np.array_equal(R, np.eye(2)):  # inliers not spread out: keep the single-pair proposal
        c, s = np.cos(proposals[best, 2]), np.sin(proposals[best, 2])
        R, t = np.array([[c, -s], [s, c]]), proposals[best, :2].copy()
    return R, t, inliers


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

    A drive whose groundings span at least ``min_baseline_m`` is rotated and moved onto them; one reached
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
    _check("closure_frames", closure_frames, (None, 4))
    _check("closure_aTb", closure_aTb, (closure_frames.shape[0], 3))
    _check("grounding_frames", grounding_frames, (None, 2))
    _check("grounding_xy_m", grounding_xy_m, (grounding_frames.shape[0], 2))
    poses = [np.array(p, dtype=np.float64) for p in chain_wTi]
    placed = list(given)

    def rotation_fixed(rows: NDArray[np.bool_], baseline_m: float = _DEGENERATE_SPREAD_M) -> bool:
        frames = {tuple(f) for f in grounding_frames[rows].tolist()}
        xy = grounding_xy_m[rows]
        return len(frames) >= 2 and float(np.linalg.norm(np.ptp(xy, axis=0))) > baseline_m

    for c in range(len(poses)):
        rows = grounding_frames[:, 0] == c
        if not placed[c] and rotation_fixed(rows, max(min_baseline_m, _DEGENERATE_SPREAD_M)):
            R, t, _ = umeyama_2d(poses[c][grounding_frames[rows, 1], :2], grounding_xy_m[rows])
            poses[c], placed[c] = transform_poses(poses[c], R, t), True

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
