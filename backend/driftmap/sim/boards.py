"""Chessboard images of a simulated camera, for calibrating it the way a technician would.

A camera with a lens (``--camera wide180``) comes with a calibration set beside the drives::

    OUT/calibration/boards.json        what a technician knows: the boards, their images, the floor board's place
    OUT/calibration/intrinsics/*.png   a hand-held board in front of the camera, at many angles (lens intrinsics)
    OUT/calibration/floor-board.png    a large board lying on the floor behind the vehicle (ground plane)
    OUT/calibration/truth.json         the true lens, mounting and camera block, kept apart for checking

``boards.json`` says, for the intrinsics, the board (inner corners ``COLSxROWS``, square side in metres) and
the image files; for the floor board, its board, image, and the floor position of its centre and the
direction of its rows in the look frame (x the way the camera looks, y left, metres; :mod:`driftmap.sim.rig`),
as a tape measure gives them. Only ``truth.json`` holds what calibration must recover.

Each image is ray-traced through the lens: every pixel is sampled at 2 x 2 points, each ray meets the board
plane, the board's pattern (black squares, a white border of one square) is looked up; a mid-grey backdrop
fills the rest; then sensor noise and 8-bit quantisation. Pixels outside the fisheye's image circle are black.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np

from driftmap.core.imaging.lens import project_rays
from driftmap.formats.drive_json import camera_to_json
from driftmap.sim.geometry import FloatArray
from driftmap.sim.rig import CameraRig

__all__ = ["FLOOR_BOARD", "HAND_BOARD", "board_image", "write_calibration_set"]

HAND_BOARD = (9, 6, 0.05)  # hand-held board: inner corners (cols, rows), square side metres
FLOOR_BOARD = (7, 5, 0.20)  # floor board: inner corners (cols, rows), square side metres
FLOOR_BOARD_CENTRE_M = (2.4, 0.0)  # floor board's centre in the look frame, metres
INTRINSIC_VIEWS = 14  # hand-held views written
_SUPER = 2  # samples per pixel along each axis
_WHITE, _BLACK, _BACKDROP = 0.82, 0.06, 0.32  # reflectances


def _board_value(xy: FloatArray, board: tuple[int, int, float]) -> FloatArray:
    """Reflectance of the board at board-plane points ``xy`` (..., 2) metres (origin: first inner corner);
    NaN off the board (past its one-square white border)."""
    cols, rows, sq = board
    i, j = np.floor(xy[..., 0] / sq), np.floor(xy[..., 1] / sq)
    inside_squares = (i >= -1) & (i <= cols - 1) & (j >= -1) & (j <= rows - 1)
    on_board = (i >= -2) & (i <= cols) & (j >= -2) & (j <= rows)
    value = np.where(((i + j) % 2 == 0) & inside_squares, _BLACK, _WHITE)
    return np.where(on_board, value, np.nan)


def board_image(
    rig: CameraRig, c_R_b: FloatArray, c_t_b: FloatArray, board: tuple[int, int, float], seed: int
) -> np.ndarray:
    """The (H, W) uint8 image of a board posed ``X_c = c_R_b X_b + c_t_b`` (metres) before a grey backdrop.

    Args:
        rig: the camera (its lens and size).
        c_R_b: (3, 3) rotation board-to-camera; the board lies in its z = 0 plane.
        c_t_b: (3,) the board's first inner corner in the camera frame, metres.
        board: inner corners (cols, rows) and square side, metres.
        seed: sensor noise seed.
    """
    w, h = rig.size_px
    offs = (np.arange(_SUPER) + 0.5) / _SUPER - 0.5
    acc = np.zeros((h, w), np.float64)
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    normal = c_R_b[:, 2]
    for du in offs:
        for dv in offs:
            rays = rig.rays_at(uu + du, vv + dv)
            along = rays @ normal
            with np.errstate(divide="ignore", invalid="ignore"):
                lam = float(normal @ c_t_b) / along
            hit = (lam > 0) & np.isfinite(lam)
            pts = (rays * np.where(hit, lam, 0.0)[..., None] - c_t_b) @ c_R_b  # board frame
            value = _board_value(pts[..., :2], board)
            acc += np.where(hit & np.isfinite(value), value, _BACKDROP)
    signal = acc / _SUPER**2
    rng = np.random.default_rng([seed, 89])
    signal = signal + rng.normal(0.0, 0.01, signal.shape)
    img = np.clip(np.rint(np.power(np.clip(signal, 0, 1), 1 / 2.2) * 255), 0, 255).astype(np.uint8)
    return np.asarray(np.where(rig.image_circle, img, 0).astype(np.uint8))


def _corners_c(c_R_b: FloatArray, c_t_b: FloatArray, board: tuple[int, int, float]) -> FloatArray:
    cols, rows, sq = board
    jj, ii = np.mgrid[-1 : rows + 1, -1 : cols + 1]
    pts = np.stack([ii.ravel() * sq, jj.ravel() * sq, np.zeros(ii.size)], axis=1)
    return np.asarray(pts @ c_R_b.T + c_t_b)


def _visible(rig: CameraRig, pts_c: FloatArray, margin_px: float) -> bool:
    """Every point is in front of the lens, inside the image circle and the frame (with a margin)."""
    lens = rig.lens
    if lens is None or np.any(pts_c[:, 2] <= 0.05):
        return False
    uv = project_rays(lens, pts_c)
    w, h = rig.size_px
    angle = np.arccos(pts_c[:, 2] / np.linalg.norm(pts_c, axis=1))
    return bool(
        np.all(uv[:, 0] > margin_px)
        and np.all(uv[:, 0] < w - 1 - margin_px)
        and np.all(uv[:, 1] > margin_px)
        and np.all(uv[:, 1] < h - 1 - margin_px)
        and np.all(angle < rig.params.max_angle_rad - 0.1)
    )


def _hand_poses(rig: CameraRig, seed: int) -> list[tuple[FloatArray, FloatArray]]:
    """Board poses in front of the camera: centred 0-70 degrees off the axis all round, tilted, 0.35-0.8 m."""
    rng = np.random.default_rng([seed, 97])
    cols, rows, sq = HAND_BOARD
    centre_b = np.array([(cols - 1) * sq / 2, (rows - 1) * sq / 2, 0.0])
    poses: list[tuple[FloatArray, FloatArray]] = []
    for attempt in range(2000):
        if len(poses) >= INTRINSIC_VIEWS:
            break
        off_axis = math.radians(rng.uniform(0, 70)) if attempt else 0.0
        azimuth = rng.uniform(-math.pi, math.pi)
        dist = rng.uniform(0.35, 0.8)
        direction = np.array(
            [
                math.sin(off_axis) * math.cos(azimuth),
                math.sin(off_axis) * math.sin(azimuth),
                math.cos(off_axis),
            ]
        )
        # The board faces the camera (its -z towards the lens), then tilts up to 35 degrees and spins.
        tilt = rng.uniform(-0.6, 0.6, size=2)
        spin = rng.uniform(-0.4, 0.4)
        z_to_dir = _rotation_between(np.array([0.0, 0.0, 1.0]), direction)
        tilt_r, _ = cv2.Rodrigues(np.array([tilt[0], tilt[1], spin]))
        c_R_b = z_to_dir @ np.asarray(tilt_r)
        c_t_b = direction * dist - c_R_b @ centre_b
        if _visible(rig, _corners_c(c_R_b, c_t_b, HAND_BOARD), 12.0):
            poses.append((c_R_b, c_t_b))
    return poses


def _rotation_between(a: FloatArray, b: FloatArray) -> FloatArray:
    """(3, 3) the smallest rotation taking unit vector ``a`` to unit vector ``b``."""
    axis = np.cross(a, b)
    s, c = float(np.linalg.norm(axis)), float(a @ b)
    if s < 1e-12:
        return np.eye(3)
    rvec = axis / s * math.atan2(s, c)
    mat, _ = cv2.Rodrigues(rvec)
    return np.asarray(mat)


def _floor_pose(rig: CameraRig) -> tuple[FloatArray, FloatArray]:
    """The floor board: centred at :data:`FLOOR_BOARD_CENTRE_M` in the look frame, rows along y (left)."""
    cols, rows, sq = FLOOR_BOARD
    # Board x (its rows) along the look frame's y, board y along -x (towards the camera), board z down.
    l_R_b = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    centre_l = np.array([*FLOOR_BOARD_CENTRE_M, 0.0])
    first_l = centre_l - l_R_b @ np.array([(cols - 1) * sq / 2, (rows - 1) * sq / 2, 0.0])
    cam_l = np.array([0.0, 0.0, rig.params.height_m])
    c_R_l = rig.lRc.T
    return np.asarray(c_R_l @ l_R_b), np.asarray(c_R_l @ (first_l - cam_l))


def write_calibration_set(out_dir: Path, rig: CameraRig, seed: int) -> None:
    """Write the calibration images, ``boards.json`` and ``truth.json`` of ``rig`` to ``out_dir``.

    The boards are shown in a calibration bay (a grey backdrop), not in the mine.
    """
    (out_dir / "intrinsics").mkdir(parents=True, exist_ok=True)
    names = []
    for k, (c_R_b, c_t_b) in enumerate(_hand_poses(rig, seed)):
        name = f"intrinsics/board-{k + 1:02d}.png"
        cv2.imwrite(str(out_dir / name), board_image(rig, c_R_b, c_t_b, HAND_BOARD, seed * 1000 + k))
        names.append(name)
    c_R_b, c_t_b = _floor_pose(rig)
    cv2.imwrite(
        str(out_dir / "floor-board.png"), board_image(rig, c_R_b, c_t_b, FLOOR_BOARD, seed * 1000 + 999)
    )
    lens = rig.lens
    boards = {
        "intrinsics": {
            "board": f"{HAND_BOARD[0]}x{HAND_BOARD[1]}",
            "square_m": HAND_BOARD[2],
            "model": rig.params.lens,
            "images": names,
        },
        "floor": {
            "board": f"{FLOOR_BOARD[0]}x{FLOOR_BOARD[1]}",
            "square_m": FLOOR_BOARD[2],
            "image": "floor-board.png",
            "centre_m": list(FLOOR_BOARD_CENTRE_M),
            "yaw_rad": math.pi / 2,
        },
        "mounting": {"y_c": rig.params.y_c_m, "forward_sign": rig.camera_model.forward_sign},
    }
    truth = {
        "lens": None
        if lens is None
        else {"model": lens.model, "K": [list(r) for r in lens.K], "distortion": list(lens.distortion)},
        "height_m": rig.params.height_m,
        "pitch_rad": rig.params.pitch_rad,
        "facing": rig.params.facing,
        "camera": camera_to_json(rig.camera_model),
    }
    (out_dir / "boards.json").write_text(json.dumps(boards, indent=2) + "\n", encoding="utf-8")
    (out_dir / "truth.json").write_text(json.dumps(truth, indent=2) + "\n", encoding="utf-8")
