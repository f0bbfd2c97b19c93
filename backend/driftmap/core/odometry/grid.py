"""The matching grid of the ground-plane visual odometry (:mod:`driftmap.core.odometry.drive`).

A camera's floor region is sampled on a grid built once per camera and parameter set (:func:`match_grid`):
for the paper's linear model an image window around the ROI, split into patches; for the homography model
a metric bird's-eye grid over the ROI footprint plus the search range, with the ROI and its nearest and
farthest depth slices as regions. Each frame is warped onto it once and patch-normalised into a pyramid
(:func:`prepare_frame`), with a quality figure (texture, sharpness, unoccluded fraction) that feeds the
step's confidence. Grid cells are ``(col, row)``; bird's-eye rows point backwards and columns right.
A camera with a lens has its frames undistorted first, over the window of the image the grid (turned by
up to the step's largest turn) can sample, with remap tables built once with the grid.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from functools import lru_cache
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.images import mask_pyramid, patch_normalise, pyramid
from driftmap.core.imaging.lens import LensMaps, lens_maps
from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.params import OdometryParams
from driftmap.errors import BadInputError

__all__ = [
    "GridFrame",
    "MatchGrid",
    "Rect",
    "Region",
    "apply_homography",
    "check_frame",
    "frame_quality",
    "grid_coords",
    "grid_masks",
    "match_grid",
    "normalised_pyramid",
    "prepare_frame",
    "warp_to_grid",
]

Rect = tuple[int, int, int, int]
Region = tuple[Rect, float, float]  # image rectangle, and the floor depth interval x_lo..x_hi (metres) kept


@dataclass(frozen=True)
class MatchGrid:
    """The matching grid of one camera and parameter set (built once, cached)."""

    model: str
    px_from_grid: NDArray[np.float64]  # (3, 3): grid (col, row, 1) -> (scaled) source pixel
    floor_from_grid: NDArray[np.float64]  # (3, 3): grid -> floor metres (homography model)
    size: tuple[int, int]  # grid (width, height), cells
    scale: float  # the source image is first resized by this (linear model)
    levels: int
    range_px: tuple[float, float]  # (x, y) search range, grid cells
    region_px: list[NDArray[np.uint8]]  # image masks of the matched regions: linear patches, or the ROI
    #                                     and its nearest and farthest depth slices (bird's-eye)
    regions: list[list[NDArray[np.float32]]]  # mask pyramid per rectangle
    valid: list[NDArray[np.float32]]  # pyramid of cells showing image content
    extent_m: float  # half the larger side of the ROI footprint, metres (shear lever of a turn)
    undistort: LensMaps | None = None  # remap tables of the camera's lens over the sampled window


@dataclass(frozen=True)
class GridFrame:
    raw: NDArray[np.uint8]  # (H, W) the frame the grid samples: undistorted when the camera has a lens
    pyr: list[NDArray[np.float32]]
    quality: float
    recorded: NDArray[np.uint8] | None = (
        None  # (H, W) the frame as recorded, when ``raw`` is its undistorted copy
    )

    def recorded_frame(self) -> NDArray[np.uint8]:
        """(H, W) uint8 the frame as recorded (what a later :func:`prepare_frame` takes again)."""
        return self.raw if self.recorded is None else self.recorded


def check_frame(frame: NDArray, camera: CameraModel, name: str) -> NDArray[np.uint8]:
    arr = np.asarray(frame)
    if arr.shape != (camera.height_px, camera.width_px):
        shape = (camera.height_px, camera.width_px)
        raise BadInputError(f"must be a gray (H, W) = {shape} image, got shape {arr.shape}", field=name)
    return arr if arr.dtype == np.uint8 else np.clip(arr, 0, 255).astype(np.uint8)


def apply_homography(hom: NDArray, pts: NDArray) -> NDArray[np.float64]:
    """Apply a (3, 3) homography to ``(..., 2)`` points."""
    pts = np.asarray(pts, dtype=np.float64)
    h = pts @ hom[:, :2].T + hom[:, 2]
    return np.asarray(h[..., :2] / h[..., 2:3])


def warp_to_grid(
    image: NDArray,
    setup: MatchGrid,
    px_from_grid: NDArray,
    interp: int = cv2.INTER_LINEAR,
    border: int = cv2.BORDER_REPLICATE,
) -> NDArray[np.float32]:
    """Sample ``image`` (full resolution) on the matching grid."""
    src = image
    if setup.scale < 1.0:
        size = (round(image.shape[1] * setup.scale), round(image.shape[0] * setup.scale))
        src = cv2.resize(image, size, interpolation=cv2.INTER_AREA if interp != cv2.INTER_NEAREST else interp)
    grid = cv2.warpPerspective(
        src, px_from_grid, setup.size, flags=interp | cv2.WARP_INVERSE_MAP, borderMode=border
    )
    return np.asarray(grid, dtype=np.float32)


def _region_images(camera: CameraModel, regions: list[Region]) -> list[NDArray[np.uint8]]:
    """{0, 1} image-resolution masks of each region (rectangle within the floor depth interval)."""
    hom = camera.homography()
    cols, rows = np.meshgrid(np.arange(camera.width_px), np.arange(camera.height_px))
    depth = np.zeros(cols.shape)
    if hom is not None:
        floor = np.einsum("ij,jhw->ihw", hom, np.stack([cols, rows, np.ones_like(cols)]).astype(np.float64))
        depth = np.where(floor[2] > 0, floor[0] / np.where(floor[2] > 0, floor[2], 1.0), -np.inf)
    out = []
    for (x, y, w, h), lo, hi in regions:
        inside = (cols >= x) & (cols < x + w) & (rows >= y) & (rows < y + h) & (depth >= lo) & (depth <= hi)
        out.append(inside.astype(np.uint8))
    return out


def grid_masks(
    camera: CameraModel, setup: MatchGrid, px_from_grid: NDArray, erode: int
) -> tuple[list[NDArray[np.float32]], NDArray[np.float32]]:
    """{0, 1} grids of the cells showing each region, and of the cells inside the frame (eroded).

    The frame and region masks are packed as bits of uint8 images (8 masks per warp); nearest-
    neighbour warping moves whole pixel values, so each bit warps exactly as its mask alone.
    """
    cols, rows = grid_coords(setup.size)
    ahead = (px_from_grid[2, 0] * cols + px_from_grid[2, 1] * rows + px_from_grid[2, 2]) > 1e-9
    full = np.ones((camera.height_px, camera.width_px), np.uint8)
    masks = [full, *setup.region_px]
    grids = []
    for g0 in range(0, len(masks), 8):
        packed = np.zeros_like(full)
        for bit, m in enumerate(masks[g0 : g0 + 8]):
            packed |= (m != 0).astype(np.uint8) << bit
        warped = warp_to_grid(packed, setup, px_from_grid, cv2.INTER_NEAREST, cv2.BORDER_CONSTANT).astype(
            np.uint8
        )
        grids += [((warped >> bit) & 1).astype(np.float32) * ahead for bit in range(len(masks[g0 : g0 + 8]))]
    valid = cv2.erode(grids[0], np.ones((3, 3), np.uint8), iterations=erode)
    return [np.asarray(g, dtype=np.float32) for g in grids[1:]], np.asarray(valid, dtype=np.float32)


@lru_cache(maxsize=16)
def grid_coords(size: tuple[int, int]) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """``(cols, rows)`` int64 ``(height, width)`` cell coordinates of a ``(width, height)`` grid
    (cached, read-only)."""
    cols, rows = np.meshgrid(np.arange(size[0]), np.arange(size[1]))
    cols.flags.writeable = rows.flags.writeable = False
    return cols, rows


def _linear_grid(camera: CameraModel, params: OdometryParams, margin: int) -> dict[str, Any]:
    """Image window around the ROI (resized so the ROI fits ``max_roi_px``), split into patches."""
    x, y, w, h = camera.ground_roi_px
    n_x, n_y = min(params.linear_patches[0], w), min(params.linear_patches[1], h)
    xs = [x + round(i * w / n_x) for i in range(n_x + 1)]
    ys = [y + round(j * h / n_y) for j in range(n_y + 1)]
    spec = [
        ((xs[i], ys[j], xs[i + 1] - xs[i], ys[j + 1] - ys[j]), -math.inf, math.inf)
        for j in range(n_y)
        for i in range(n_x)
    ]
    scale = min(1.0, params.max_roi_px / max(w, h))
    lever = abs(camera.y_c_m + camera.y_h_m)
    rx = scale * (math.tan(params.max_turn_rad) * lever + params.max_lateral_m) / camera.k_x_m_per_px
    ry = scale * params.max_step_m / camera.k_y_m_per_px
    x0, y0 = math.floor(x * scale - rx) - margin, math.floor(y * scale - ry) - margin
    return {
        "spec": spec, "scale": scale, "range_px": (rx, ry), "roi_min": min(w / n_x, h / n_y) * scale,
        "size": (math.ceil(w * scale + 2 * rx) + 2 * margin, math.ceil(h * scale + 2 * ry) + 2 * margin),
        "px_from_grid": np.array([[1.0, 0.0, x0], [0.0, 1.0, y0], [0.0, 0.0, 1.0]]),
        "floor_from_grid": np.eye(3), "extent_m": 0.0,
    }  # fmt: skip


def _birdseye_grid(camera: CameraModel, hom: NDArray, params: OdometryParams, margin: int) -> dict[str, Any]:
    """Metric grid over the ROI footprint plus the search ranges; regions: ROI, nearest and farthest
    20 % of its depth range (the horizon self-calibration slices)."""
    x, y, w, h = camera.ground_roi_px
    u = np.array([x, x + w / 2, x + w, x + w, x + w, x + w / 2, x, x], dtype=np.float64)
    v = np.array([y, y, y, y + h / 2, y + h, y + h, y + h, y + h / 2], dtype=np.float64)
    if np.any(hom[2, 0] * u + hom[2, 1] * v + hom[2, 2] <= 0):
        raise BadInputError("reaches above the horizon of ground_homography", field="ground_roi")
    f = apply_homography(hom, np.stack([u, v], axis=1))
    (near_x, near_y), (far_x, far_y) = f.min(axis=0), f.max(axis=0)
    span_x = params.max_step_m
    span_y = math.sin(params.max_turn_rad) * abs(far_x + camera.y_c_m) + params.max_lateral_m
    ext_x, ext_y = far_x - near_x + 2 * span_x, far_y - near_y + 2 * span_y
    res = max(params.bev_res_m, max(ext_x, ext_y) / (params.bev_max_px - 2 * margin))
    top, left = far_x + span_x + margin * res, far_y + span_y + margin * res
    floor_from_grid = np.array([[0.0, -res, top], [-res, 0.0, left], [0.0, 0.0, 1.0]])
    cut = 0.2 * (far_x - near_x)
    rect = (x, y, w, h)
    return {
        "spec": [(rect, -math.inf, math.inf), (rect, -math.inf, near_x + cut), (rect, far_x - cut, math.inf)],
        "scale": 1.0, "range_px": (span_y / res, span_x / res),
        "roi_min": min(far_x - near_x, far_y - near_y) / res,
        "size": (math.ceil(ext_y / res) + 2 * margin, math.ceil(ext_x / res) + 2 * margin),
        "px_from_grid": np.linalg.inv(hom) @ floor_from_grid, "floor_from_grid": floor_from_grid,
        "extent_m": 0.5 * max(far_x - near_x, far_y - near_y),
    }  # fmt: skip


@lru_cache(maxsize=16)
def match_grid(camera: CameraModel, params: OdometryParams) -> MatchGrid:
    """Build the matching grid: image window (linear) or metric bird's-eye grid (homography)."""
    hom = camera.homography()
    model = params.model if params.model != "auto" else ("homography" if hom is not None else "linear")
    if model == "homography" and hom is None:
        raise BadInputError("'homography' needs a camera with ground_homography", field="model")
    margin = 2 * params.refine_radius_px + 3
    g = (
        _linear_grid(camera, params, margin)
        if hom is None or model == "linear"
        else _birdseye_grid(camera, hom, params, margin)
    )
    rx, ry = g["range_px"]
    levels = 0  # coarsest level: regions keep coarse_min_px across, or the range is small enough
    while g["roi_min"] / 2 ** (levels + 1) >= params.coarse_min_px and max(rx, ry) / 2**levels > 4:
        levels += 1
    base = MatchGrid(
        model, g["px_from_grid"], g["floor_from_grid"], g["size"], g["scale"], levels, (rx, ry),
        _region_images(camera, g["spec"]), [], [], g["extent_m"],
    )  # fmt: skip
    masks, valid = grid_masks(camera, base, base.px_from_grid, max(1, params.patch_px // 2))
    regions = [mask_pyramid(m, levels) for m in masks]
    undistort = None
    if camera.lens is not None:
        window = _sampled_window(camera, base)
        undistort = lens_maps(camera.lens, (camera.width_px, camera.height_px), window)
    return dataclasses.replace(base, regions=regions, valid=mask_pyramid(valid, levels), undistort=undistort)


def _sampled_window(camera: CameraModel, setup: MatchGrid, margin: float = 0.1) -> Rect:
    """Image rectangle ``(x, y, w, h)`` around the ROI and the grid's footprint, grown by ``margin``
    of its size on each side (room for the turned grids of a step), clipped to the frame."""
    width, height = setup.size
    t = np.linspace(0.0, 1.0, 17)
    border = np.concatenate(
        [np.stack([t * width, np.zeros_like(t)], 1), np.stack([t * width, np.full_like(t, height)], 1),
         np.stack([np.zeros_like(t), t * height], 1), np.stack([np.full_like(t, width), t * height], 1)]
    )  # fmt: skip
    hom = setup.px_from_grid
    w_h = border @ hom[2, :2] + hom[2, 2]
    pts = apply_homography(hom, border[w_h > 1e-9]) / setup.scale
    x, y, w, h = camera.ground_roi_px
    pts = np.vstack([pts[np.all(np.isfinite(pts), axis=1)], [[x, y], [x + w, y + h]]])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    grow = margin * (hi - lo)
    x0, y0 = np.maximum(np.floor(lo - grow), 0).astype(int)
    x1 = min(int(np.ceil(hi[0] + grow[0])), camera.width_px)
    y1 = min(int(np.ceil(hi[1] + grow[1])), camera.height_px)
    return (int(x0), int(y0), x1 - int(x0), y1 - int(y0))


def frame_quality(raw: NDArray[np.uint8], camera: CameraModel, params: OdometryParams) -> float:
    """Texture x sharpness x unoccluded fraction of a frame's ROI, in [0, 1]."""
    x, y, w, h = camera.ground_roi_px
    roi = raw[y : y + h, x : x + w].astype(np.float32)
    contrast = float((roi - cv2.blur(roi, (9, 9))).std())
    texture = 1.0 - math.exp(-contrast / params.texture_ref)
    # Re-blur test: a sharp image loses much gradient under a 1-px Gaussian, a blurred one little.
    soft = cv2.GaussianBlur(roi, (0, 0), 1.0)
    g_sharp = float(np.abs(np.diff(roi, axis=0)).mean() + np.abs(np.diff(roi, axis=1)).mean())
    g_soft = float(np.abs(np.diff(soft, axis=0)).mean() + np.abs(np.diff(soft, axis=1)).mean())
    blur = min(1.0, max(0.0, 1.0 - g_soft / g_sharp) / params.blur_ref) if g_sharp > 0 else 0.0
    mean = cv2.blur(roi, (5, 5))
    local_std = np.sqrt(np.maximum(cv2.blur(roi * roi, (5, 5)) - mean * mean, 0.0))
    bad = (roi <= params.saturated_low) | (roi >= params.saturated_high) | (local_std < params.flat_std)
    return texture * blur * (1.0 - float(bad.mean()))


def normalised_pyramid(grid: NDArray, levels: int, params: OdometryParams) -> list[NDArray[np.float32]]:
    return [patch_normalise(level, params.patch_px, params.flat_std) for level in pyramid(grid, levels)]


def prepare_frame(
    frame: NDArray[np.uint8], camera: CameraModel, setup: MatchGrid, params: OdometryParams
) -> GridFrame:
    recorded = None
    if setup.undistort is not None:
        recorded, frame = frame, setup.undistort.apply(frame)
    grid = warp_to_grid(frame, setup, setup.px_from_grid)
    if setup.model == "linear" and params.linear_blur_px > 0:  # fine grain does not survive the zoom
        grid = np.asarray(cv2.GaussianBlur(grid, (0, 0), params.linear_blur_px), dtype=np.float32)
    pyr = normalised_pyramid(grid, setup.levels, params)
    return GridFrame(frame, pyr, frame_quality(frame, camera, params), recorded)
