"""Surface albedo and light of the synthetic tunnel, per hit point (used by :mod:`driftmap.sim.render`).

All functions take hit points in local metres (float32 arrays of N points) and return float32 (N,).
Floor: gravel tile x floor patches tile, darker wheel ruts 1.2 m either side of the nearest
centreline, puddles and painted spots. Roof: shotcrete tile, emissive light tubes and painted bands
(edges anti-aliased over the pixel footprint). Walls: the site strip x a fine rock tile. Roof lights
also illuminate everything near them.
"""

from __future__ import annotations

import math

import numpy as np

from driftmap.sim.textures import F32, Levels
from driftmap.sim.world import World

__all__ = ["bumped_cos", "floor_albedo", "light_from_roof_lights", "roof_albedo", "wall_albedo"]

RUT_OFFSET_M = 1.2  # wheel ruts this far either side of the centreline
RUT_WIDTH_M = 0.3  # and this wide (Gaussian half-width)
RUT_RANGE_M = 15.0  # ruts are drawn on floor closer than this to the camera
TUBE_HALF_LENGTH_M = 0.6  # a light tube is 1.2 m x 0.18 m
TUBE_HALF_WIDTH_M = 0.09


def floor_albedo(
    world: World,
    x: F32,
    y: F32,
    rho: F32,
    lv_fine: Levels,
    lv_mid: Levels,
    cam_xy: tuple[float, float],
    rut_depth: float,
    max_range_m: float,
) -> F32:
    """Albedo of floor points (N,) at horizontal distance ``rho`` (N,) from the camera foot ``cam_xy``."""
    alb = world.floor_fine.sample(x, y, lv_fine) * world.floor_mid.sample(x, y, lv_mid)
    ox, oy = cam_xy
    a, b = world.centre_p0, world.centre_p1
    near = np.flatnonzero(_seg_dist(a, b, ox, oy) < RUT_RANGE_M + 3.0)
    close = np.flatnonzero(rho < RUT_RANGE_M)
    if near.size and close.size:
        xc, yc = x[close], y[close]
        best = np.full(close.shape, np.inf, np.float32)
        for k in near:
            best = np.minimum(best, _point_seg_dist(xc, yc, a[k], b[k]))
        rut = np.exp(-(((best - np.float32(RUT_OFFSET_M)) * np.float32(1 / RUT_WIDTH_M)) ** 2))
        alb[close] *= np.float32(1.0) - np.float32(rut_depth) * rut
    sp = world.spots
    if len(sp):
        for k in np.flatnonzero(np.hypot(sp[:, 0] - ox, sp[:, 1] - oy) - sp[:, 2] < max_range_m):
            d = np.hypot(x - sp[k, 0], y - sp[k, 1])
            m = np.clip((sp[k, 2] - d) * np.float32(10.0) + np.float32(0.5), 0.0, 1.0)
            alb *= np.float32(1.0) - m * (np.float32(1.0) - sp[k, 3])
            if sp[k, 4] > 0:
                alb = alb * (np.float32(1.0) - m) + m * sp[k, 4]
    return np.asarray(alb, dtype=np.float32)


def roof_albedo(
    world: World,
    x: F32,
    y: F32,
    footprint_m: F32,
    lv: Levels,
    cam_xy: tuple[float, float],
    emission_gain: float,
    max_range_m: float,
) -> tuple[F32, F32]:
    """(albedo, emission) of roof points (N,) whose pixels cover ``footprint_m`` (N,) of roof."""
    alb = world.roof.sample(x, y, lv)
    emission = np.zeros(x.shape, np.float32)
    if x.size == 0:
        return alb, emission
    ox, oy = cam_xy
    inv_fp = np.float32(1.0) / np.maximum(footprint_m, np.float32(1e-3))
    for table, emissive in ((world.lights, True), (world.roof_marks, False)):
        if len(table) == 0:
            continue
        for k in np.flatnonzero(np.hypot(table[:, 0] - ox, table[:, 1] - oy) < max_range_m + 20.0):
            c, s = np.float32(math.cos(float(table[k, 2]))), np.float32(math.sin(float(table[k, 2])))
            dx, dy = x - table[k, 0], y - table[k, 1]
            along, across = np.abs(dx * c + dy * s), np.abs(dy * c - dx * s)
            half_len, half_wid = (
                (TUBE_HALF_LENGTH_M, TUBE_HALF_WIDTH_M) if emissive else (table[k, 3], table[k, 4])
            )
            m = np.clip((np.float32(half_len) - along) * inv_fp + np.float32(0.5), 0.0, 1.0)
            m *= np.clip((np.float32(half_wid) - across) * inv_fp + np.float32(0.5), 0.0, 1.0)
            alb *= np.float32(1.0) - m
            if emissive:
                emission += np.float32(emission_gain) * m
            else:
                alb += m * table[k, 5]
    return alb, emission


def wall_albedo(world: World, s: F32, z: F32, lv_4cm: Levels, lv_1cm: Levels) -> F32:
    """Albedo of wall points at strip arc length ``s`` and height ``z`` (N,), grouped by the pyramid
    levels of 4 cm (the strip) and 1 cm (the rock grain) textures."""
    strip = world.strip.sample(s, z, lv_4cm)
    fine = world.wall_fine.sample(s, z, lv_1cm)
    return np.asarray(strip * fine, dtype=np.float32)


def light_from_roof_lights(
    world: World,
    x: F32,
    y: F32,
    z: F32,
    cam_xy: tuple[float, float],
    power: float,
    max_range_m: float,
    count: int = 4,
) -> F32:
    """Illumination (N,) at points (local metres) from the ``count`` roof lights nearest the camera."""
    out = np.zeros(x.shape, np.float32)
    lights = world.lights
    if len(lights) == 0:
        return out
    d_cam = np.hypot(lights[:, 0] - cam_xy[0], lights[:, 1] - cam_xy[1])
    lz = np.float32(world.height_m - 0.2)
    for k in np.argsort(d_cam, kind="stable")[:count]:
        if d_cam[k] > max_range_m:
            break
        d2 = (x - lights[k, 0]) ** 2 + (y - lights[k, 1]) ** 2 + (z - lz) ** 2
        out += np.float32(power) / (d2 + np.float32(1.0))
    return out


def bumped_cos(cos_inc: F32, slope_u: F32, slope_v: F32, ray_u: F32, ray_v: F32, strength: float) -> F32:
    """Cosine of incidence of the headlight on a bumpy surface, (N,).

    The surface is displaced towards the camera's side by a height field h(u, v) with slopes (h_u, h_v);
    its normal tilts to n - h_u e_u - h_v e_v, so with the light at the camera (unit ray d)
    cos = (cos_flat + h_u (d . e_u) + h_v (d . e_v)) / sqrt(1 + h_u^2 + h_v^2).

    Args:
        cos_inc: (N,) cosine on the flat surface.
        slope_u, slope_v: (N,) height slopes along the surface axes u, v (metres per metre).
        ray_u, ray_v: (N,) components of the unit ray along u and v.
        strength: multiplies the slopes.
    """
    gu, gv = slope_u * np.float32(strength), slope_v * np.float32(strength)
    cos = (cos_inc + gu * ray_u + gv * ray_v) / np.sqrt(np.float32(1.0) + gu * gu + gv * gv)
    return np.asarray(np.clip(cos, 0.0, 1.0), dtype=np.float32)


def _seg_dist(a: F32, b: F32, x: float, y: float) -> F32:
    """Distance of point (x, y) to each segment a[i]-b[i], (K,)."""
    e = b - a
    L2 = np.maximum(np.sum(e * e, axis=1), 1e-9)
    u = np.clip(((x - a[:, 0]) * e[:, 0] + (y - a[:, 1]) * e[:, 1]) / L2, 0.0, 1.0)
    return np.asarray(np.hypot(a[:, 0] + u * e[:, 0] - x, a[:, 1] + u * e[:, 1] - y), dtype=np.float32)


def _point_seg_dist(x: F32, y: F32, a: F32, b: F32) -> F32:
    """Distance of points (N,) to segment a-b."""
    ex, ey = b[0] - a[0], b[1] - a[1]
    L2 = np.float32(max(float(ex * ex + ey * ey), 1e-9))
    u = np.clip(((x - a[0]) * ex + (y - a[1]) * ey) / L2, 0.0, 1.0)
    return np.asarray(np.hypot(a[0] + u * ex - x, a[1] + u * ey - y), dtype=np.float32)
