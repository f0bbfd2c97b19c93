"""Small 2-D polyline helpers shared by the layout, the motion planner and the world builder.

Polylines are ``(N, 2)`` float64 arrays of metres, N >= 2, consecutive points distinct.
"""

from __future__ import annotations

import itertools

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "FloatArray",
    "arc_lengths",
    "heading_at",
    "point_at",
    "polyline_length",
    "project",
    "resample",
    "split_at",
    "sub_polyline",
]

FloatArray = NDArray[np.float64]


def arc_lengths(poly: FloatArray) -> FloatArray:
    """Cumulative arc length at each vertex, ``(N,)`` metres, starting at 0."""
    seg = np.hypot(*np.diff(poly, axis=0).T)
    return np.concatenate([[0.0], np.cumsum(seg)])


def polyline_length(poly: FloatArray) -> float:
    """Total length of ``poly`` in metres."""
    return float(np.sum(np.hypot(*np.diff(poly, axis=0).T)))


def point_at(poly: FloatArray, s_m: float) -> FloatArray:
    """The point at arc length ``s_m`` (clamped to the ends), ``(2,)``."""
    s = arc_lengths(poly)
    s_m = float(np.clip(s_m, 0.0, s[-1]))
    return np.array([np.interp(s_m, s, poly[:, 0]), np.interp(s_m, s, poly[:, 1])])


def heading_at(poly: FloatArray, s_m: float) -> float:
    """Direction of travel (radians, CCW from +x) of the segment holding arc length ``s_m``."""
    s = arc_lengths(poly)
    i = int(np.clip(np.searchsorted(s, s_m, side="right") - 1, 0, len(poly) - 2))
    d = poly[i + 1] - poly[i]
    return float(np.arctan2(d[1], d[0]))


def sub_polyline(poly: FloatArray, s0_m: float, s1_m: float) -> FloatArray:
    """The piece of ``poly`` between arc lengths ``s0_m < s1_m`` (clamped), ``(M, 2)``."""
    s = arc_lengths(poly)
    s0_m, s1_m = float(np.clip(s0_m, 0.0, s[-1])), float(np.clip(s1_m, 0.0, s[-1]))
    inner = (s > s0_m + 1e-9) & (s < s1_m - 1e-9)
    pts = [point_at(poly, s0_m), *poly[inner], point_at(poly, s1_m)]
    return np.asarray(pts, dtype=np.float64)


def split_at(poly: FloatArray, cuts_m: list[float]) -> list[FloatArray]:
    """Split ``poly`` at the sorted arc lengths ``cuts_m`` (strictly inside) into len(cuts)+1 pieces."""
    bounds = [0.0, *cuts_m, polyline_length(poly)]
    return [sub_polyline(poly, a, b) for a, b in itertools.pairwise(bounds)]


def project(poly: FloatArray, p: FloatArray) -> tuple[float, float]:
    """Arc length of the point of ``poly`` closest to ``p`` and the distance to it (metres)."""
    a, b = poly[:-1], poly[1:]
    d = b - a
    L2 = np.maximum(np.sum(d * d, axis=1), 1e-12)
    t = np.clip(np.sum((p - a) * d, axis=1) / L2, 0.0, 1.0)
    q = a + t[:, None] * d
    dist = np.hypot(*(q - p).T)
    i = int(np.argmin(dist))
    return float(arc_lengths(poly)[i] + t[i] * np.sqrt(L2[i])), float(dist[i])


def resample(poly: FloatArray, step_m: float) -> FloatArray:
    """Points every ``step_m`` along ``poly`` (the last one exactly at its end), ``(M, 2)``."""
    s = arc_lengths(poly)
    n = max(int(np.ceil(s[-1] / step_m)), 1)
    q = np.linspace(0.0, s[-1], n + 1)
    return np.stack([np.interp(q, s, poly[:, 0]), np.interp(q, s, poly[:, 1])], axis=1)
