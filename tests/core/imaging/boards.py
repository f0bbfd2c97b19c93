"""Synthetic chessboard and ChArUco views through a known lens, rendered by ray casting (calibration tests).

Each pixel is split into ``ss x ss`` samples; each sample's ray (from the lens's exact undistortion) is cut
with the board plane, and the board's colour there is averaged. The board has ``(cols + 1) x (rows + 1)``
squares around its inner corners, a white margin one square wide, and a mid-grey world behind it. A ChArUco
board's squares and markers are OpenCV's own drawing of it, sampled where each ray meets the board.
"""

from __future__ import annotations

from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.calibration import Board
from driftmap.core.imaging.lens import Lens, distort_points, undistort_points

PINHOLE = Lens(
    "pinhole", ((420.0, 0.0, 322.0), (0.0, 418.0, 236.0), (0.0, 0.0, 1.0)), (-0.28, 0.09, 0.001, -0.0008, 0.0)
)
FISHEYE = Lens(
    "fisheye", ((190.0, 0.0, 318.0), (0.0, 190.0, 242.0), (0.0, 0.0, 1.0)), (0.04, -0.01, 0.003, -0.001)
)
SIZE = (640, 480)
BOARD = Board(8, 6, 0.03)
CHARUCO = Board(9, 6, 0.03, marker_m=0.022, dictionary="DICT_4X4_50")
_TEXELS_PER_SQUARE = 60


@lru_cache(maxsize=4)
def _rays(lens: Lens, size: tuple[int, int], ss: int) -> tuple[NDArray[np.float32], NDArray[np.bool_]]:
    """(H * ss, W * ss, 3) rays (z = 1) of every sample, and where they are valid.

    Rays are exact at pixel centres and linearly interpolated to the samples (cv2.resize puts a sample of
    pixel u at u + (i + 0.5) / ss - 0.5, i = 0..ss-1, which is where the samples belong).
    """
    width, height = size
    uu, vv = np.meshgrid(np.arange(width, dtype=np.float64), np.arange(height, dtype=np.float64))
    raw = np.stack([uu.ravel(), vv.ravel()], axis=1)
    ideal = undistort_points(lens, raw)
    ok = np.all(np.isfinite(ideal), axis=1)
    back = distort_points(lens, np.where(ok[:, None], ideal, 0.0))
    ok &= np.linalg.norm(back - raw, axis=1) < 0.05
    k = lens.matrix()
    x = np.where(ok, (ideal[:, 0] - k[0, 2]) / k[0, 0], 0.0).reshape(height, width)
    y = np.where(ok, (ideal[:, 1] - k[1, 2]) / k[1, 1], 0.0).reshape(height, width)
    up = (width * ss, height * ss)
    rays = np.stack(
        [
            cv2.resize(x.astype(np.float32), up),
            cv2.resize(y.astype(np.float32), up),
            np.ones(up[::-1], np.float32),
        ],
        axis=2,
    )
    valid = cv2.resize(ok.reshape(height, width).astype(np.uint8), up, interpolation=cv2.INTER_NEAREST) > 0
    return rays, valid


def render_view(
    lens: Lens, rvec: NDArray, tvec: NDArray, board: Board = BOARD, size: tuple[int, int] = SIZE, ss: int = 3
) -> NDArray[np.uint8]:
    """(H, W) uint8 image of ``board`` at pose (rvec, tvec) (board-to-camera, metres)."""
    rays, ok = _rays(lens, size, ss)
    rot, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64))
    t = np.asarray(tvec, dtype=np.float64).ravel()
    normal = rot[:, 2]
    denom = rays @ normal
    s = float(normal @ t) / np.where(np.abs(denom) > 1e-12, denom, 1e-12)
    pts = (rays * s[..., None] - t) @ rot  # board coordinates, metres
    sq = board.square_m
    bx, by = pts[..., 0] / sq, pts[..., 1] / sq
    hit = ok & (s > 0)
    squares = hit & (bx >= -1) & (bx < board.cols) & (by >= -1) & (by < board.rows)
    margin = hit & (bx >= -2) & (bx < board.cols + 1) & (by >= -2) & (by < board.rows + 1)
    if board.is_charuco:
        texture = _charuco_texture(board)
        tu = ((bx + 1) * _TEXELS_PER_SQUARE - 0.5).astype(np.float32)
        tv = ((by + 1) * _TEXELS_PER_SQUARE - 0.5).astype(np.float32)
        drawn = cv2.remap(texture, tu, tv, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        value = np.where(squares, 20.0 + drawn * (215.0 / 255.0), np.where(margin, 235.0, 128.0))
    else:
        black = squares & ((np.floor(bx) + np.floor(by)) % 2 == 0)
        value = np.where(black, 20.0, np.where(margin, 235.0, 128.0))
    width, height = size
    img = value.reshape(height, ss, width, ss).mean(axis=(1, 3))
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


@lru_cache(maxsize=2)
def _charuco_texture(board: Board) -> NDArray[np.float32]:
    """OpenCV's drawing of the ChArUco board's squares, ``_TEXELS_PER_SQUARE`` texels a square, 0-255."""
    assert board.marker_m is not None
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, board.dictionary))
    squares = (board.cols + 1, board.rows + 1)
    drawing = cv2.aruco.CharucoBoard(squares, board.square_m, board.marker_m, dictionary)
    size = (squares[0] * _TEXELS_PER_SQUARE, squares[1] * _TEXELS_PER_SQUARE)
    return np.asarray(drawing.generateImage(size, marginSize=0, borderBits=1), dtype=np.float32)


def board_poses(
    count: int, distance_m: float, seed: int = 3, board: Board = BOARD
) -> list[tuple[NDArray, NDArray]]:
    """``count`` board poses (rvec, tvec): tilted up to ~35 degrees, centred near the axis, varied offset."""
    rng = np.random.default_rng(seed)
    centre = np.array([(board.cols - 1) * board.square_m / 2, (board.rows - 1) * board.square_m / 2, 0.0])
    poses = []
    for _ in range(count):
        rvec = np.array([rng.uniform(-0.6, 0.6), rng.uniform(-0.6, 0.6), rng.uniform(-0.4, 0.4)])
        rot, _ = cv2.Rodrigues(rvec)
        target = np.array(
            [rng.uniform(-0.35, 0.35) * distance_m, rng.uniform(-0.25, 0.25) * distance_m, distance_m]
        )
        poses.append((rvec, target - rot @ centre))
    return poses


def floor_pose(
    board: Board,
    centre_m: tuple[float, float],
    yaw_rad: float,
    pitch_deg: float = 35.0,
    height_m: float = 2.0,
) -> tuple[NDArray, NDArray]:
    """(rvec, tvec) of a board lying on the floor, seen by :func:`tests.floor_frames.pinhole_camera`'s mount.

    The board's centre is at ``centre_m`` (x forward, y left) and its rows point at ``yaw_rad``.
    """
    phi = np.radians(pitch_deg)
    r1, r2 = np.array([0.0, -np.sin(phi), np.cos(phi)]), np.array([-1.0, 0.0, 0.0])  # floor x, y in camera
    camera_from_floor = np.stack([r1, r2, np.cross(r1, r2)], axis=1)
    t = np.array([0.0, height_m * np.cos(phi), height_m * np.sin(phi)])
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    mid = np.array([(board.cols - 1) / 2, (board.rows - 1) / 2, 0.0]) * board.square_m
    rot = camera_from_floor @ turn
    tvec = camera_from_floor @ (np.array([*centre_m, 0.0]) - turn @ mid) + t
    rvec, _ = cv2.Rodrigues(rot)
    return rvec.ravel(), tvec


def wall_texture(size: int = 1024, seed: int = 4) -> NDArray[np.float32]:
    """(size, size) float32 smooth random grey texture, 0-255 (blobs a few dozen texels across)."""
    rng = np.random.default_rng(seed)
    coarse = rng.uniform(0.0, 255.0, size=(size // 16, size // 16)).astype(np.float32)
    fine = cv2.resize(coarse, (size, size), interpolation=cv2.INTER_CUBIC)
    return np.asarray(cv2.GaussianBlur(fine, (0, 0), 4.0), dtype=np.float32)


def render_wall(
    lens: Lens,
    texture: NDArray[np.float32],
    half_m: float = 3.0,
    distance_m: float = 1.0,
    size: tuple[int, int] = SIZE,
    ss: int = 2,
) -> NDArray[np.uint8]:
    """(H, W) uint8 image of a textured wall facing the camera ``distance_m`` ahead, ``texture`` spanning
    ``-half_m .. half_m`` in x (right) and y (down); rays that miss it, or have no pinhole ray, see grey 128."""
    rays, ok = _rays(lens, size, ss)
    side = texture.shape[0]
    tex_u = ((rays[..., 0] * distance_m + half_m) / (2 * half_m) * side - 0.5).astype(np.float32)
    tex_v = ((rays[..., 1] * distance_m + half_m) / (2 * half_m) * side - 0.5).astype(np.float32)
    seen = cv2.remap(
        texture, tex_u, tex_v, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=128.0
    )
    value = np.where(ok, seen, 128.0)
    width, height = size
    img = value.reshape(height, ss, width, ss).mean(axis=(1, 3))
    return np.clip(np.round(img), 0, 255).astype(np.uint8)
