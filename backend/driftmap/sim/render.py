"""Vectorised ray caster: one grayscale frame of the vehicle camera from a pose in the world.

The tunnel cross-section is a box: flat floor (z = 0), flat roof (z = H), vertical walls. Because
walls are vertical, every ray hits the same wall as any other ray of the same azimuth, so walls are
found once per frame for ``azimuth_bins`` azimuths (2-D ray-segment intersection against the
segments within ``max_range_m``), then each pixel intersects the line of its bin's segment exactly.
Floor and roof hits in the vehicle frame are fixed per pixel and precomputed, so a floor pixel only
needs its world position (rotate + translate) and texture lookups.

Radiance = albedo * (headlight + roof lights) + emission. The headlight sits at the camera: intensity
falls off with 1 / distance^2 (clipped near the camera) times the cosine of incidence and a beam
pattern. Then exposure gain, vignetting, shot and read noise, gamma, 8-bit quantisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.sim import shading
from driftmap.sim.rig import CameraRig
from driftmap.sim.textures import F32, level_for
from driftmap.sim.world import World

__all__ = ["RENDER_DEFAULT", "RenderParams", "Renderer"]

_LUT_SIZE = 1 << 14  # linear signal quantisation before the gamma lookup


@dataclass(frozen=True)
class RenderParams:
    """Lighting, sensor and culling settings of the renderer."""

    max_range_m: float = 45.0  # walls beyond are culled; floor or roof beyond (without a wall) is black
    azimuth_bins: int = 1024  # azimuths cast in 2-D per frame
    headlight: float = 4.5  # radiance of albedo 1 at 1 m, normal incidence, on the beam axis
    near_clip_m: float = 1.2  # distances below this count as this for the 1/d^2 fall-off
    beam_pitch_rad: float = math.radians(12.0)  # headlight axis below the horizontal
    beam_exponent: float = 3.0  # beam pattern cos(angle off axis)^exponent
    light_power: float = 3.0  # roof light: radiance of albedo 1 at 1 m
    light_emission: float = 6.0  # radiance of a light tube seen directly
    bloom: float = 0.35  # weight of the blurred glow around emitters
    rut_depth: float = 0.25  # darkening of the wheel ruts
    vignette: float = 0.35  # brightness lost at the image corners
    read_noise: float = 0.008  # sensor read noise (linear units of full scale)
    shot_noise: float = 0.015  # shot noise scale: sigma = shot_noise * sqrt(signal)
    gamma: float = 1.0 / 2.2  # output gamma
    noise: bool = True  # add sensor noise (tests turn it off)


RENDER_DEFAULT = RenderParams()


@dataclass(frozen=True, eq=False)
class _Plane:
    """Pixels whose rays hit a horizontal plane (floor or roof) and where, in the vehicle frame."""

    px: NDArray[np.int64]  # (P,) flat pixel indices
    xy: F32  # (P, 2) hit point in the foot frame (x forward, y left), metres
    rho: F32  # (P,) horizontal distance, metres
    dist: F32  # (P,) 3-D distance from the camera, metres
    cos: F32  # (P,) cosine of incidence
    footprint: F32  # (P,) metres of plane under one pixel


def _plane(d: NDArray[np.float64], idx: NDArray[np.int64], height_m: float, pix_rad: float) -> _Plane:
    t = height_m / d[idx, 2]
    cos_inc = np.abs(d[idx, 2])
    return _Plane(
        idx,
        (t[:, None] * d[idx, :2]).astype(np.float32),
        (t * np.hypot(d[idx, 0], d[idx, 1])).astype(np.float32),
        t.astype(np.float32),
        cos_inc.astype(np.float32),
        (t * pix_rad / np.sqrt(cos_inc)).astype(np.float32),
    )


class Renderer:
    """Renders frames of ``rig`` in ``world``; precomputes everything that is fixed per pixel."""

    def __init__(self, world: World, rig: CameraRig, params: RenderParams = RENDER_DEFAULT) -> None:
        self.world, self.rig, self.params = world, rig, params
        w, h = rig.size_px
        self.shape = (h, w)
        d = rig.rays_f.reshape(-1, 3).astype(np.float64)
        rh = np.hypot(d[:, 0], d[:, 1])
        psi = np.arctan2(d[:, 1], d[:, 0])
        self.cos_psi, self.sin_psi = np.cos(psi).astype(np.float32), np.sin(psi).astype(np.float32)
        self.rh = rh.astype(np.float32)
        self.slope = (d[:, 2] / rh).astype(np.float32)
        lo, hi = psi.min() - 1e-6, psi.max() + 1e-6
        self.bin_psi = np.linspace(lo, hi, params.azimuth_bins)
        self.bin_of_px = np.rint((psi - lo) / (hi - lo) * (params.azimuth_bins - 1)).astype(np.int32)
        cam_h = rig.params.height_m
        self.pix_rad = 1.0 / rig.params.focal_px
        self.floor = _plane(d, np.flatnonzero(d[:, 2] < -1e-4), -cam_h, self.pix_rad)
        self.roof = _plane(d, np.flatnonzero(d[:, 2] > 1e-4), world.height_m - cam_h, self.pix_rad)
        self.floor_lv_fine = level_for(self.floor.footprint, 0.01, len(world.floor_fine.levels))
        self.floor_lv_mid = level_for(self.floor.footprint, 0.08, len(world.floor_mid.levels))
        self.roof_lv = level_for(self.roof.footprint, 0.02, len(world.roof.levels))
        axis = np.array([math.cos(params.beam_pitch_rad), 0.0, -math.sin(params.beam_pitch_rad)])
        self.beam = (np.clip(d @ axis, 0.0, 1.0) ** params.beam_exponent).astype(np.float32)
        u, v = np.meshgrid(np.linspace(-1, 1, w), np.linspace(-1, 1, h))
        self.vignette = (1.0 - params.vignette * ((u**2 + v**2) / 2).reshape(-1)).astype(np.float32)
        self.gamma_lut = np.rint(np.power(np.linspace(0.0, 1.0, _LUT_SIZE), params.gamma) * 255.0).astype(
            np.uint8
        )

    def _cast_walls(self, ox: float, oy: float, yaw: float) -> tuple[NDArray[np.int64], F32, F32, F32]:
        """Nearest culled wall segment of every azimuth bin (-1: none) and the culled segments'
        starts relative to the camera foot, unit directions and strip arc starts."""
        w = self.world
        p0, p1 = w.wall_p0.astype(np.float64), w.wall_p1.astype(np.float64)
        e = p1 - p0
        rel = np.array([ox, oy]) - p0
        L2 = np.maximum(np.sum(e * e, axis=1), 1e-12)
        u = np.clip(np.sum(rel * e, axis=1) / L2, 0.0, 1.0)
        keep = np.flatnonzero(np.hypot(*(rel - u[:, None] * e).T) < self.params.max_range_m)
        p0k, ek = p0[keep] - np.array([ox, oy]), e[keep]
        ang = yaw + self.bin_psi
        seg = np.full(len(ang), -1, np.int64)
        if len(keep):
            dx, dy = np.cos(ang)[:, None], np.sin(ang)[:, None]
            denom = dx * ek[None, :, 1] - dy * ek[None, :, 0]
            with np.errstate(divide="ignore", invalid="ignore"):
                r = (p0k[None, :, 0] * ek[None, :, 1] - p0k[None, :, 1] * ek[None, :, 0]) / denom
                s = (p0k[None, :, 0] * dy - p0k[None, :, 1] * dx) / denom
            ok = (np.abs(denom) > 1e-9) & (r > 1e-3) & (s >= -1e-6) & (s <= 1.0 + 1e-6)
            r = np.where(ok, r, np.inf)
            best = np.argmin(r, axis=1)
            seg = np.where(np.isfinite(r[np.arange(len(ang)), best]), best, -1)
        unit = ek / np.sqrt(L2[keep])[:, None]
        return seg, p0k.astype(np.float32), unit.astype(np.float32), w.wall_s0[keep]

    def radiance(self, x_m: float, y_m: float, yaw_rad: float) -> tuple[F32, F32]:
        """Linear radiance (H, W) lit by headlight and roof lights, and emission (H, W), at a pose.

        Args:
            x_m, y_m: the floor point under the camera, local metres (grid - world.origin_xy).
            yaw_rad: vehicle heading, radians CCW from +x.
        """
        pr, world = self.params, self.world
        n = self.shape[0] * self.shape[1]
        cam = (x_m, y_m)
        roof_h = np.float32(world.height_m)
        cy, sy = np.float32(math.cos(yaw_rad)), np.float32(math.sin(yaw_rad))
        dirx = cy * self.cos_psi - sy * self.sin_psi
        diry = sy * self.cos_psi + cy * self.sin_psi
        seg_bin, p0, unit, s0 = self._cast_walls(x_m, y_m, yaw_rad)
        seg = seg_bin[self.bin_of_px]
        has_wall = seg >= 0
        seg[~has_wall] = 0
        ux, uy = unit[seg, 0], unit[seg, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            rho_w = (p0[seg, 0] * uy - p0[seg, 1] * ux) / (dirx * uy - diry * ux)
        rho_w[~(has_wall & (rho_w > 0.01))] = np.inf
        z_w = np.float32(self.rig.params.height_m) + rho_w * self.slope
        is_wall = (z_w >= 0.0) & (z_w <= roof_h)
        hx, hy, hz = np.zeros(n, np.float32), np.zeros(n, np.float32), np.zeros(n, np.float32)
        dist = np.full(n, np.inf, np.float32)
        cos_inc, albedo, emission = np.zeros(n, np.float32), np.zeros(n, np.float32), np.zeros(n, np.float32)
        ox, oy = np.float32(x_m), np.float32(y_m)
        for plane in (self.floor, self.roof):
            hit = ~is_wall[plane.px] & (plane.rho < np.minimum(rho_w[plane.px], np.float32(pr.max_range_m)))
            j = np.flatnonzero(hit)
            pix = plane.px[j]
            vx, vy = plane.xy[j, 0], plane.xy[j, 1]
            rx, ry = cy * vx - sy * vy, sy * vx + cy * vy
            hx[pix], hy[pix] = rx, ry
            dist[pix], cos_inc[pix] = plane.dist[j], plane.cos[j]
            if plane is self.floor:
                albedo[pix] = shading.floor_albedo(
                    world,
                    rx + ox,
                    ry + oy,
                    plane.rho[j],
                    self.floor_lv_fine[j],
                    self.floor_lv_mid[j],
                    cam,
                    pr.rut_depth,
                    pr.max_range_m,
                )
            else:
                hz[pix] = roof_h
                albedo[pix], emission[pix] = shading.roof_albedo(
                    world,
                    rx + ox,
                    ry + oy,
                    plane.footprint[j],
                    self.roof_lv[j],
                    cam,
                    pr.light_emission,
                    pr.max_range_m,
                )
        wi = np.flatnonzero(is_wall)
        if wi.size:
            r, k = rho_w[wi], seg[wi]
            dxw, dyw = dirx[wi], diry[wi]
            hx[wi], hy[wi], hz[wi] = r * dxw, r * dyw, z_w[wi]
            dist[wi] = r / self.rh[wi]
            cos_inc[wi] = np.abs(unit[k, 1] * dxw - unit[k, 0] * dyw) * self.rh[wi]
            s = s0[k] + (hx[wi] - p0[k, 0]) * unit[k, 0] + (hy[wi] - p0[k, 1]) * unit[k, 1]
            footprint = (
                dist[wi] * np.float32(self.pix_rad) / np.sqrt(np.maximum(cos_inc[wi], np.float32(0.05)))
            )
            albedo[wi] = shading.wall_albedo(world, s, z_w[wi], footprint.astype(np.float32))
        d_clip = np.maximum(dist, np.float32(pr.near_clip_m))
        light = np.float32(pr.headlight) * self.beam * cos_inc / (d_clip * d_clip)
        light += shading.light_from_roof_lights(
            world, hx + ox, hy + oy, hz, cam, pr.light_power, pr.max_range_m
        )
        return (albedo * light).reshape(self.shape), emission.reshape(self.shape)

    def render(
        self, x_m: float, y_m: float, yaw_rad: float, exposure: float, noise_seed: int | list[int]
    ) -> NDArray[np.uint8]:
        """The 8-bit frame (H, W) at a pose (local metres, radians), exposure gain and noise seed."""
        pr = self.params
        rad, emission = self.radiance(x_m, y_m, yaw_rad)
        if pr.bloom > 0 and float(emission.max()) > 0:
            rad += emission + np.float32(pr.bloom) * cv2.GaussianBlur(emission, (0, 0), 4.0)
        sig = rad.reshape(-1) * self.vignette * np.float32(exposure)
        if pr.noise:
            rng = np.random.default_rng(noise_seed)
            sigma = np.sqrt(
                np.float32(pr.read_noise**2) + np.float32(pr.shot_noise**2) * np.maximum(sig, 0.0)
            )
            sig += sigma * rng.standard_normal(sig.size, dtype=np.float32)
        code = (np.clip(sig, 0.0, 1.0) * np.float32(_LUT_SIZE - 1) + np.float32(0.5)).astype(np.int32)
        return np.asarray(self.gamma_lut[code].reshape(self.shape))
