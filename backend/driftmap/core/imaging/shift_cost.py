"""The cost of one shift in :func:`~driftmap.core.imaging.registration.register_shift`, both ways round.

:class:`TwoSidedCost` is eq. 3 of [SSLAM] made two-sided and overlap-normalised: each image's
region-of-interest is compared with the other image at the shift, weighted by the other's valid-pixel
mask, and the two sides' sums are pooled. Mask facts (bounding boxes, whether a box is all valid) are
remembered per mask, since a drive compares many frames through the same few masks. :func:`gradient` is
the central-difference image gradient the sub-pixel refinement uses.
"""

from __future__ import annotations

import math
import threading
from collections import OrderedDict
from functools import lru_cache
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["TwoSidedCost", "gradient"]


def _bbox(mask: NDArray) -> tuple[int, int, int, int]:
    """Bounding box (r0, r1, c0, c1) of a mask's support; a 1x1 box of zeros when it is empty."""
    rows = np.flatnonzero(mask.any(axis=1))
    cols = np.flatnonzero(mask.any(axis=0))
    if rows.size == 0:
        return 0, 1, 0, 1
    return int(rows[0]), int(rows[-1]) + 1, int(cols[0]), int(cols[-1]) + 1


_FACTS: OrderedDict[tuple[str, int], tuple[NDArray, Any]] = OrderedDict()
_FACTS_LOCK = threading.Lock()
_FACTS_SIZE = 64  # masks remembered: a drive's fixed pyramids plus the turned ones of a few frames


def _mask_fact(kind: str, mask: NDArray) -> Any:
    """What the search derives from a mask, computed once per mask object (the masks a drive's odometry
    passes are fixed, or made anew per frame; none is changed after use).

    ``kind`` "roi": ``(box, ROI inside the box (contiguous), its sum as float, any support)``; "holes": the
    ``(H + 1, W + 1)`` int32 summed-area table of the pixels that are not 1 (partners missing or partial).
    """
    key = (kind, id(mask))
    with _FACTS_LOCK:
        hit = _FACTS.get(key)
        if hit is not None and hit[0] is mask:
            _FACTS.move_to_end(key)
            return hit[1]
    if kind == "roi":
        box = _bbox(mask)
        box_roi = np.ascontiguousarray(mask[box[0] : box[1], box[2] : box[3]])
        fact: Any = (box, box_roi, float(box_roi.sum()), bool(box_roi.any()))
    else:
        fact = cv2.integral(np.ascontiguousarray(mask != 1, dtype=np.uint8))
    with _FACTS_LOCK:
        _FACTS[key] = (mask, fact)  # the reference keeps the id from being reused while cached
        while len(_FACTS) > _FACTS_SIZE:
            _FACTS.popitem(last=False)
    return fact


def _all_ones(holes: NDArray, r0: int, r1: int, c0: int, c1: int) -> bool:
    """Whether every pixel of the box ``[r0, r1) x [c0, c1)`` of the mask behind ``holes`` is 1."""
    return int(holes[r1, c1] - holes[r0, c1] - holes[r1, c0] + holes[r0, c0]) == 0


@lru_cache(maxsize=256)
def _box_grid(r0: int, r1: int, c0: int, c1: int) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Row and column coordinates ``(r1 - r0, c1 - c0)`` float32 of a box (cached, read-only)."""
    rows, cols = np.mgrid[r0:r1, c0:c1].astype(np.float32)
    rows.flags.writeable = cols.flags.writeable = False
    return rows, cols


def gradient(img: NDArray) -> tuple[NDArray, NDArray]:
    """``np.gradient`` of an ``(H, W)`` float image without its per-call overhead: ``(d/drow, d/dcol)``,
    each ``(H, W)`` of the input dtype (central differences inside, one-sided on the border: the
    same operations, so bit-identical)."""
    if min(img.shape) < 2:
        np.gradient(img)  # raises as numpy does
    if img.ndim != 2:
        raise ValueError(f"_gradient needs an (H, W) image, got shape {img.shape}")
    g_y, g_x = np.empty_like(img), np.empty_like(img)
    np.subtract(img[2:], img[:-2], out=g_y[1:-1])
    g_y[1:-1] /= 2.0
    np.subtract(img[1], img[0], out=g_y[0])
    np.subtract(img[-1], img[-2], out=g_y[-1])
    np.subtract(img[:, 2:], img[:, :-2], out=g_x[:, 1:-1])
    g_x[:, 1:-1] /= 2.0
    np.subtract(img[:, 1], img[:, 0], out=g_x[:, 0])
    np.subtract(img[:, -1], img[:, -2], out=g_x[:, -1])
    return g_y, g_x


class TwoSidedCost:
    """Cost of one shift on one pyramid level, both ways round (see :func:`register_shift`)."""

    def __init__(
        self, a: NDArray, b: NDArray, roi_a: NDArray, valid_a: NDArray, roi_b: NDArray, valid_b: NDArray,
        side: str = "both",
    ) -> None:  # fmt: skip
        self.a, self.b = a, b
        # (box, ROI inside the box, image holding the ROI, other image, other's valid mask, sign of s)
        self.sides = []
        # per side: the ROI box's sum, and the summed-area table of the other's invalid pixels
        self.sums: list[tuple[float, NDArray]] = []
        for name, roi, img, other, valid, sign in (
            ("a", roi_a, a, b, valid_b, 1),
            ("b", roi_b, b, a, valid_a, -1),
        ):
            box, box_roi, box_sum, support = _mask_fact("roi", roi)
            if side in ("both", name) and support:
                self.sides.append((box, box_roi, img, other, valid, sign))
                self.sums.append((box_sum, _mask_fact("holes", valid)))
        self.den_max = float(sum(side_[1].sum() for side_ in self.sides))
        if self.den_max <= 0:
            raise ValueError("the ROI mask is empty at some pyramid level; lower the number of levels")
        self.memo: dict[tuple[int, int], tuple[float, float]] = {}
        # per side: the ROI box of its image, and scratch arrays for the difference and the weights
        self.scratch = [
            (
                img[r0:r1, c0:c1],
                np.empty(roi.shape, np.result_type(img, other)),
                np.empty(roi.shape, np.result_type(roi, valid)),
            )
            for (r0, r1, c0, c1), roi, img, other, valid, _ in self.sides
        ]

    def __call__(self, dx: int, dy: int) -> tuple[float, float]:
        """(mean absolute difference, weight) at integer shift (dx, dy); inf if too little overlaps."""
        key = (dx, dy)
        if key not in self.memo:
            self.memo[key] = self._compute(dx, dy)
        return self.memo[key]

    def _compute(self, dx: int, dy: int) -> tuple[float, float]:
        height, width = self.a.shape
        num = den = 0.0
        # a's ROI against b at p + s, and b's ROI against a at q - s; partners inside the frame only.
        for ((r0, r1, c0, c1), roi, _, other, valid, sign), (box, diff, weight), (roi_sum, holes) in zip(
            self.sides, self.scratch, self.sums, strict=True
        ):
            sx, sy = sign * dx, sign * dy
            if min(r0 + sy, c0 + sx) < 0 or r1 + sy > height or c1 + sx > width:
                continue
            moved = (slice(r0 + sy, r1 + sy), slice(c0 + sx, c1 + sx))
            if box.dtype == other.dtype == np.float32:  # one pass; OpenCV float absdiff is |a - b| too
                cv2.absdiff(box, other[moved], dst=diff)
            else:
                np.abs(np.subtract(box, other[moved], out=diff), out=diff)
            if weight.dtype == roi.dtype and _all_ones(holes, r0 + sy, r1 + sy, c0 + sx, c1 + sx):
                # every partner is valid: the weights are the ROI itself
                num += float(np.vdot(diff, roi))
                den += roi_sum
            else:
                np.multiply(roi, valid[moved], out=weight)
                num += float(np.vdot(diff, weight))
                den += float(weight.sum())
        if den < 0.25 * self.den_max:
            return np.inf, den
        return num / den, den

    def refine(self, dx: int, dy: int, iterations: int = 5) -> tuple[float, float]:
        """Sub-pixel shift near integer (dx, dy) by Gauss-Newton on the masked two-sided SSD.

        Each side's partner image is resampled bilinearly at the current shift and linearised
        (Lucas-Kanade); the shift stays within one pixel of (dx, dy); a singular system (no
        texture) stops the iteration. The Jacobian of a side is ``sign`` times the partner's
        gradient; the sign is applied to the dot products (exact, rounding is sign-symmetric).
        """
        fx, fy = float(dx), float(dy)
        height, width = self.a.shape
        for _ in range(iterations):
            hess, grad = np.zeros((2, 2)), np.zeros(2)
            for ((r0, r1, c0, c1), roi, img, other, valid, sign), (_, holes) in zip(
                self.sides, self.sums, strict=True
            ):
                off_x, off_y = np.float32(sign * fx), np.float32(sign * fy)
                # float32 rounding is monotonic: the extremes of the sample maps are the box corners'
                if (
                    min(np.float32(c0) + off_x, np.float32(r0) + off_y) < 1
                    or np.float32(c1 - 1) + off_x > width - 2
                    or np.float32(r1 - 1) + off_y > height - 2
                ):
                    continue
                rows, cols = _box_grid(r0, r1, c0, c1)
                map_x, map_y = cols + off_x, rows + off_y
                warped = cv2.remap(other, map_x, map_y, cv2.INTER_LINEAR)
                lo_x, hi_x, lo_y, hi_y = (
                    math.floor(off_x),
                    math.ceil(off_x),
                    math.floor(off_y),
                    math.ceil(off_y),
                )
                if valid.dtype == roi.dtype and _all_ones(holes, r0 + lo_y, r1 + hi_y, c0 + lo_x, c1 + hi_x):
                    w = roi  # every nearest partner is valid
                else:
                    w = roi * cv2.remap(valid, map_x, map_y, cv2.INTER_NEAREST)
                g_y, g_x = gradient(warped)
                w_g = (w * g_x, w * g_y)
                resid = img[r0:r1, c0:c1] - warped
                for i in range(2):
                    grad[i] += sign * float(np.vdot(w_g[i], resid))
                    hess[i, 0] += float(np.vdot(w_g[i], g_x))
                    hess[i, 1] += float(np.vdot(w_g[i], g_y))
            if np.linalg.det(hess) <= 1e-12 * max(1.0, float(np.trace(hess))) ** 2:
                break
            step = np.linalg.solve(hess, grad)
            fx, fy = (
                float(np.clip(fx + step[0], dx - 1, dx + 1)),
                float(np.clip(fy + step[1], dy - 1, dy + 1)),
            )
            if float(np.abs(step).max()) < 1e-3:
                break
        return fx, fy

    def ssd_surface(self, rx: int, ry: int) -> NDArray[np.float64]:
        """Two-sided masked mean squared difference for all shifts, ``(2 ry + 1, 2 rx + 1)``.

        Exact weighted SSD from four correlations per side (``cv2.matchTemplate`` TM_CCORR, FFT for
        large templates): ``sum m v (t - s)^2 = corr(v, m t^2) - 2 corr(v s, m t) + corr(v s^2, m)``.
        """
        num = np.zeros((2 * ry + 1, 2 * rx + 1))
        den = np.zeros_like(num)
        for (r0, r1, c0, c1), roi, tmpl, img, valid, sign in self.sides:
            pad = (
                (max(0, ry - r0), max(0, r1 + ry - img.shape[0])),
                (max(0, rx - c0), max(0, c1 + rx - img.shape[1])),
            )
            window = (
                slice(r0 - ry + pad[0][0], r1 + ry + pad[0][0]),
                slice(c0 - rx + pad[1][0], c1 + rx + pad[1][0]),
            )
            v = np.pad(valid, pad)[window]
            sv = np.pad(img, pad)[window] * v
            t = tmpl[r0:r1, c0:c1] * roi
            terms = [
                cv2.matchTemplate(v, np.ascontiguousarray(t * t), cv2.TM_CCORR),
                cv2.matchTemplate(sv, np.ascontiguousarray(t), cv2.TM_CCORR),
                cv2.matchTemplate(np.ascontiguousarray(sv * sv), roi, cv2.TM_CCORR),
                cv2.matchTemplate(v, roi, cv2.TM_CCORR),
            ]
            ssd = np.maximum(terms[0] - 2.0 * terms[1] + terms[2], 0.0)
            step = sign  # b's ROI placed at offset o in a is the shift -o
            num += ssd[::step, ::step]
            den += terms[3][::step, ::step]
        out = np.full(num.shape, np.inf)
        ok = den >= 0.25 * self.den_max
        out[ok] = num[ok] / den[ok]
        return out
