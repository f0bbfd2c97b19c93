"""SE(2) geometry of drives: composing, inverting and dead-reckoning poses, and rigid fits between point sets.

Poses are (N, 3) float64 arrays of rows [x_m, y_m, yaw_rad]; ``wTi`` is frame i in the survey (world)
frame w, ``iTj`` is frame j in frame i. :mod:`driftmap.core.graph.placement` uses these to put the drives
into the survey frame before the pose graph pins them.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from driftmap.core.types import F64

DEGENERATE_SPREAD_M = 1e-3  # points closer together than this fix no rotation


def check_shape(name: str, array: NDArray, shape: tuple[int | None, ...]) -> None:
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
    check_shape("iTj", steps, (None, 3))
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
    check_shape("src", a, (None, 2))
    check_shape("dst", b, (a.shape[0], 2))
    if a.shape[0] == 0:
        raise ValueError("umeyama_2d needs at least one point")
    mu_a, mu_b = a.mean(axis=0), b.mean(axis=0)
    da, db = a - mu_a, b - mu_b
    var_a = float((da**2).sum()) / a.shape[0]
    if np.sqrt(var_a) < DEGENERATE_SPREAD_M:
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
    check_shape("src_poses", src, (None, 3))
    check_shape("dst_poses", dst, (src.shape[0], 3))
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
