"""The renderable world: wall segments, textures and features in a local float32-safe frame.

Mine-grid coordinates (~1e4-6e4 m) lose millimetres in float32, so the world keeps everything
relative to ``origin_xy`` (the layout's south-west corner rounded to 100 m): local = grid - origin.
Wall segments come from the rings of the tunnel outline in ring order; each has its start arc length
``s0`` on the wall strip (rings are separated by a 2 m gap).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from driftmap.sim.decor import decorate
from driftmap.sim.geometry import FloatArray
from driftmap.sim.layout import Layout
from driftmap.sim.strip import StripAtlas
from driftmap.sim.textures import (
    F32,
    MipTexture,
    floor_fine_texture,
    floor_mid_texture,
    roof_texture,
    slopes,
    wall_fine_texture,
    wall_relief,
)

__all__ = ["World", "build_world"]

_RING_GAP_M = 2.0


@dataclass(frozen=True, eq=False)
class World:
    """Everything the renderer needs; positions are local metres (grid - ``origin_xy``), float32."""

    origin_xy: tuple[float, float]  # grid coordinates of the local origin
    height_m: float  # floor-to-roof height
    wall_p0: F32  # (M, 2) wall segment starts
    wall_p1: F32  # (M, 2) wall segment ends
    wall_s0: F32  # (M,) strip arc length at each start
    centre_p0: F32  # (C, 2) centreline segment starts (for wheel ruts)
    centre_p1: F32  # (C, 2) centreline segment ends
    lights: F32  # (K, 3) x, y, heading of roof light tubes
    spots: F32  # (P, 5) x, y, radius, albedo gain, paint albedo (0: none) of floor patches
    roof_marks: F32  # (Q, 6) x, y, heading, half length, half width, albedo of painted roof bands
    strip: StripAtlas  # wall pictures and materials over (arc length, height)
    floor_fine: MipTexture  # gravel, 1 cm texels
    floor_mid: MipTexture  # floor brightness patches, 8 cm texels
    wall_fine: MipTexture  # rock grain, 1 cm texels
    roof: MipTexture  # shotcrete, mesh, bolts, 2 cm texels
    floor_slope_x: MipTexture  # gravel height slope along world x (bump shading), 1 cm texels
    floor_slope_y: MipTexture  # ... along world y
    wall_slope_s: MipTexture  # rock relief slope along the wall arc length, 4 cm texels
    wall_slope_z: MipTexture  # ... along the height

    def to_local(self, xy_grid: FloatArray) -> FloatArray:
        """Grid metres (..., 2) -> local metres (..., 2), float64."""
        return np.asarray(np.asarray(xy_grid, dtype=np.float64) - np.asarray(self.origin_xy))

    def with_spots(self, extra: FloatArray) -> World:
        """A copy with extra floor patches (K, 5) in grid metres: x, y, radius, albedo gain, paint.

        Inside a patch the albedo is multiplied by the gain, then replaced by the paint albedo if > 0.
        """
        extra = np.asarray(extra, dtype=np.float64).reshape(-1, 5).copy()
        extra[:, :2] = self.to_local(extra[:, :2])
        return replace(self, spots=np.concatenate([self.spots, extra.astype(np.float32)]))


def wall_segments(layout: Layout) -> tuple[FloatArray, FloatArray, FloatArray, float]:
    """Wall segments of every ring, (M, 2) starts and ends in grid metres, (M,) arc starts, total arc."""
    p0s, p1s, s0s = [], [], []
    s = 0.0
    for ring in layout.walls:
        seg = np.hypot(*np.diff(ring, axis=0).T)
        keep = seg > 1e-6
        a, b, seg = ring[:-1][keep], ring[1:][keep], seg[keep]
        p0s.append(a)
        p1s.append(b)
        s0s.append(s + np.concatenate([[0.0], np.cumsum(seg)[:-1]]))
        s += float(seg.sum()) + _RING_GAP_M
    return np.concatenate(p0s), np.concatenate(p1s), np.concatenate(s0s), s


def build_world(layout: Layout, seed: int) -> World:
    """Build the renderable world of ``layout``; deterministic per ``seed``."""
    rng = np.random.default_rng([seed, 23])
    p0, p1, s0, total = wall_segments(layout)
    decor = decorate(layout, p0, p1, s0, total, np.random.default_rng([seed, 29]))
    allx = np.concatenate([p0[:, 0], p1[:, 0]])
    ally = np.concatenate([p0[:, 1], p1[:, 1]])
    origin = (math.floor(allx.min() / 100.0) * 100.0, math.floor(ally.min() / 100.0) * 100.0)
    o = np.asarray(origin)
    centre = [(e.polyline[:-1], e.polyline[1:]) for e in layout.edges]

    def loc(xy: FloatArray) -> F32:
        return np.asarray(xy - o, dtype=np.float32)

    def with_xy(table: FloatArray) -> F32:
        out = table.copy()
        out[:, :2] -= o
        return out.astype(np.float32)

    floor_albedo, floor_height = floor_fine_texture(rng)
    fgx, fgy = slopes(floor_height, 0.01)
    wgs, wgz = slopes(wall_relief(rng), 0.04)
    return World(
        origin_xy=(float(origin[0]), float(origin[1])),
        height_m=layout.height_m,
        wall_p0=loc(p0),
        wall_p1=loc(p1),
        wall_s0=s0.astype(np.float32),
        centre_p0=loc(np.concatenate([a for a, _ in centre])),
        centre_p1=loc(np.concatenate([b for _, b in centre])),
        lights=with_xy(decor.lights),
        spots=with_xy(decor.spots),
        roof_marks=with_xy(decor.roof_marks),
        strip=decor.strip,
        floor_fine=MipTexture.build(floor_albedo, 0.01, 6),
        floor_mid=MipTexture.build(floor_mid_texture(rng), 0.08, 4),
        wall_fine=MipTexture.build(wall_fine_texture(rng), 0.01, 5),
        roof=MipTexture.build(roof_texture(rng), 0.02, 5),
        floor_slope_x=MipTexture.build(fgx, 0.01, 6),
        floor_slope_y=MipTexture.build(fgy, 0.01, 6),
        wall_slope_s=MipTexture.build(wgs, 0.04, 4),
        wall_slope_z=MipTexture.build(wgz, 0.04, 4),
    )
