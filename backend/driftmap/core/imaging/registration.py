"""Shift registration: the sub-pixel content motion between two images by coarse-to-fine masked SAD.

The visual odometry (:mod:`driftmap.core.odometry.drive`) measures each step as the motion of the floor between
two frames: :func:`register_shift` searches the coarsest pyramid level exhaustively (a masked squared
difference computed by correlation), carries its best local minima down the pyramid by downhill SAD
windows (the two-sided, overlap-normalised cost of eq. 3 of [SSLAM] with the region-of-interest and
valid-pixel masks as weights) and refines the winner to sub-pixel (Gauss-Newton on the SSD, or a parabola
per axis). Shift convention as in :mod:`driftmap.core.imaging.sad`: content moving right and down in ``b`` gives a
positive ``(dx, dy)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.shift_cost import TwoSidedCost

__all__ = ["ShiftMatch", "register_shift"]


@dataclass(frozen=True)
class ShiftMatch:
    """Result of :func:`register_shift`.

    Attributes:
        shift_px: ``(dx, dy)`` sub-pixel content motion from image ``a`` to image ``b``, level-0 px.
        cost: mean absolute difference at the integer minimum (level 0).
        distinctiveness: ``1 - best / second-best`` local minimum of the coarse exhaustive (squared
            difference) search, in [0, 1]; near 0 when another shift matches about as well.
        at_range_edge: the minimum lies on the border of the searched range (motion maybe larger).
        overlap: weighted pixels compared at the minimum / ROI pixels of the sides used, in [0, 1].
    """

    shift_px: tuple[float, float]
    cost: float
    distinctiveness: float
    at_range_edge: bool
    overlap: float


def _parabola(c_minus: float, c_0: float, c_plus: float) -> float:
    """Offset in [-0.5, 0.5] of the vertex of the parabola through three equally spaced costs."""
    curv = c_minus - 2.0 * c_0 + c_plus
    if not np.isfinite(curv) or curv <= 0:
        return 0.0
    return float(np.clip(0.5 * (c_minus - c_plus) / curv, -0.5, 0.5))


def _coarse_minima(surf: NDArray, candidates: int) -> tuple[list[tuple[int, int]], float]:
    """The best ``candidates`` 3x3 local minima ``(x, y)`` of a cost surface, and 1 - best/second."""
    finite = np.isfinite(surf)
    if not finite.any():
        return [(surf.shape[1] // 2, surf.shape[0] // 2)], 0.0
    filled = np.where(finite, surf, surf[finite].max() * 2 + 1).astype(np.float32)
    minima = np.argwhere((filled <= cv2.erode(filled, np.ones((3, 3), np.uint8))) & finite)
    values = filled[minima[:, 0], minima[:, 1]]
    order = np.argsort(values)
    second = values[order[1]] if values.size > 1 else float(surf[finite].max())
    distinct = float(np.clip(1.0 - values[order[0]] / second, 0.0, 1.0)) if second > 0 else 0.0
    return [(int(minima[i, 1]), int(minima[i, 0])) for i in order[:candidates]], distinct


def _descend(
    cost: TwoSidedCost, dx: int, dy: int, radius: int, max_steps: int = 20
) -> tuple[int, int, float]:
    """Move a (2 radius + 1)^2 window downhill until its minimum is interior."""
    for _ in range(max_steps):
        window = [
            (cost(dx + i, dy + j)[0], dx + i, dy + j)
            for j in range(-radius, radius + 1)
            for i in range(-radius, radius + 1)
        ]
        best, bx, by = min(window)
        if (bx, by) == (dx, dy) or not np.isfinite(best):
            return dx, dy, cost(dx, dy)[0]
        dx, dy = bx, by
    return dx, dy, cost(dx, dy)[0]


def register_shift(
    a: list[NDArray],
    b: list[NDArray],
    roi: list[NDArray],
    valid: list[NDArray],
    max_dx: float,
    max_dy: float,
    *,
    roi_b: list[NDArray] | None = None,
    valid_b: list[NDArray] | None = None,
    candidates: int = 3,
    radius: int = 1,
    start_px: tuple[int, int] | None = None,
    also_from_px: tuple[int, int] | None = None,
    subpixel: str = "parabola",
    side: str = "both",
) -> ShiftMatch:
    """Find the content motion from image ``a`` to image ``b`` by coarse-to-fine masked SAD.

    The cost of an integer shift ``s`` is two-sided: the mean absolute difference of ``a`` over its
    region of interest against ``b`` at ``p + s``, pooled with ``b`` over its region of interest
    against ``a`` at ``q - s``, counting only partners inside the frame (``valid``). Motion in
    either direction keeps a full-size comparison even when the ROI touches the frame border. The
    coarsest level is searched exhaustively over the whole range with the same two-sided masked
    cost in squared form (computed by correlation, so the range costs little); its best
    ``candidates`` local minima are carried down, each refined by a downhill SAD window of
    ``radius`` per level; the best wins and its level-0 minimum is refined to sub-pixel per axis
    (parabola or equiangular-line fit).

    Args:
        a: pyramid of the first image, ``[(H, W), (H/2, W/2), ...]`` float32 (e.g. normalised).
        b: pyramid of the second image, same shapes.
        roi: pyramid of the {0, 1} region of interest of ``a`` (and of ``b`` unless ``roi_b``).
        valid: pyramid of the {0, 1} pixels of ``a`` holding image content (and of ``b``).
        max_dx: horizontal search range at level 0, pixels.
        max_dy: vertical search range at level 0, pixels.
        roi_b: ROI pyramid of ``b`` when it differs from ``a``'s (e.g. ``b`` was warped differently).
        valid_b: valid-pixel pyramid of ``b`` when it differs.
        candidates: coarse local minima refined.
        radius: refinement window radius per level, pixels.
        start_px: skip the exhaustive search and descend from this shift, in pixels of the coarsest
            level given (level 0 when the pyramids have one level).
        also_from_px: one more start for the descent beside the exhaustive search's minima (e.g. a motion
            prior), in pixels of the coarsest level given; the lowest level-0 cost wins as for the others,
            and the distinctiveness still comes from the exhaustive search.
        subpixel: "lk" (Gauss-Newton on the two-sided SSD, most accurate) or "parabola" (per-axis
            fit of the SAD values around the minimum).
        side: "both" (two-sided), or only "a"'s ROI against ``b`` or only "b"'s ROI against ``a``;
            one side puts the correspondence exactly at that image's ROI.

    Returns:
        :class:`ShiftMatch`.

    Raises:
        ValueError: pyramids of different lengths or shapes, or an empty ROI.
    """
    levels = len(a) - 1
    roi_b = roi if roi_b is None else roi_b
    valid_b = valid if valid_b is None else valid_b
    pyramids = (a, b, roi, valid, roi_b, valid_b)
    if levels < 0 or any(len(p) != levels + 1 for p in pyramids):
        raise ValueError("a, b and the masks must be pyramids of the same length")
    for i in range(levels + 1):
        if a[i].ndim != 2 or any(p[i].shape != a[i].shape for p in pyramids):
            raise ValueError(f"pyramid level {i}: shapes differ")
    costs = [
        TwoSidedCost(a[i], b[i], roi[i], valid[i], roi_b[i], valid_b[i], side) for i in range(levels + 1)
    ]
    distinct = 1.0
    top = levels
    if start_px is not None:
        seeds = [start_px]
    else:
        rx, ry = int(np.ceil(max_dx / 2**top)), int(np.ceil(max_dy / 2**top))
        seeds, distinct = _coarse_minima(costs[top].ssd_surface(rx, ry), candidates)
        seeds = [(sx - rx, sy - ry) for sx, sy in seeds]
        if also_from_px is not None:
            seeds.append(also_from_px)
    results = []
    for sx, sy in seeds:
        for level in range(top, -1, -1):
            sx, sy, c = _descend(costs[level], sx, sy, radius)
            if level:
                sx, sy = 2 * sx, 2 * sy
        results.append((c, sx, sy))
    c0, sx, sy = min(results)
    cost = costs[0]
    if subpixel == "lk":
        fx, fy = cost.refine(sx, sy)
    else:
        fx = sx + _parabola(cost(sx - 1, sy)[0], c0, cost(sx + 1, sy)[0])
        fy = sy + _parabola(cost(sx, sy - 1)[0], c0, cost(sx, sy + 1)[0])
    return ShiftMatch(
        shift_px=(fx, fy),
        cost=float(c0),
        distinctiveness=distinct,
        at_range_edge=abs(sx) >= max_dx or abs(sy) >= max_dy,
        overlap=min(1.0, float(cost(sx, sy)[1] / cost.den_max)),
    )
