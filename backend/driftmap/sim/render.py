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
from driftmap.sim.textures import F32, Levels, level_for
from driftmap.sim.world import World

__all__ = ["RENDER_DEFAULT", "RenderParams", "Renderer"]

_LUT_SIZE = 1 << 14  # linear signal quantisation before the gamma lookup


@dataclass(frozen=True)
class RenderParams:
    """Lighting, sensor and culling settings of the renderer."""

    max_range_m: float = 45.0  # walls beyond are culled; floor or roof beyond (without a wall) is black
    azimuth_bins: int = 1024  # azimuths cast in 2-D per frame
    headlight: float = 7.0  # radiance of albedo 1 at 1 m, normal incidence, on the beam axis
    near_clip_m: float = 1.2  # distances below this count as this for the 1/d^2 fall-off
    beam_pitch_rad: float = math.radians(12.0)  # headlight axis below the horizontal
    beam_exponent: float = 3.0  # beam pattern cos(angle off axis)^exponent
    light_power: float = 3.0  # roof light: radiance of albedo 1 at 1 m
    light_emission: float = 6.0  # radiance of a light tube seen directly
    bloom: float = 0.35  # weight of the blurred glow around emitters
    rut_depth: float = 0.25  # darkening of the wheel ruts
    bump: float = 2.0  # strength of the bump shading of gravel and rock relief (0: flat)
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


@dataclass(frozen=True, eq=False)
class _Walls:
    """Wall segments within range of the camera, and the one each azimuth bin hits."""

    seg_of_bin: NDArray[np.int64]  # (B,) index into the culled segments, -1 where no wall is in range
    p0: F32  # (K, 2) segment starts relative to the camera foot, metres
    unit: F32  # (K, 2) unit directions
    s0: F32  # (K,) strip arc length at the starts


@dataclass(eq=False)
class _Frame:
    """Per-pixel working arrays of one frame (N = H * W, float32); hit points relative to the camera foot."""

    cam: tuple[float, float]  # camera foot, local metres
    hx: F32
    hy: F32
    hz: F32
    dist: F32  # 3-D distance of the hit, inf where nothing is hit
    cos: F32  # cosine of incidence of the headlight
    albedo: F32
    emission: F32
    dirx: F32  # horizontal unit ray direction in the world
    diry: F32

    @staticmethod
    def empty(n: int, cam: tuple[float, float]) -> _Frame:
        z = [np.zeros(n, np.float32) for _ in range(8)]
        return _Frame(cam, z[0], z[1], z[2], np.full(n, np.inf, np.float32), z[3], z[4], z[5], z[6], z[7])


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
        rh = np.maximum(rh, 1e-9)  # a fisheye may look straight down
        self.rh = rh.astype(np.float32)
        self.slope = (d[:, 2] / rh).astype(np.float32)
        # Azimuth bins span the azimuths seen, measured from the way the camera looks (a rear camera's
        # azimuths straddle +-pi in the foot frame); at least two bins per pixel column.
        self.mount_yaw = 0.0 if rig.params.facing == "front" else math.pi
        look = (psi - self.mount_yaw + math.pi) % (2 * math.pi) - math.pi
        bins = max(params.azimuth_bins, 2 * w)
        lo, hi = look.min() - 1e-6, look.max() + 1e-6
        self.bin_psi = np.linspace(lo, hi, bins) + self.mount_yaw
        self.bin_of_px = np.rint((look - lo) / (hi - lo) * (bins - 1)).astype(np.int32)
        # A fisheye's sensor is dark outside its image circle (None: a pinhole sees with every pixel).
        self.seen = None if rig.lens is None else rig.image_circle.reshape(-1).astype(np.float32)
        cam_h = rig.params.height_m
        self.pix_rad = 1.0 / rig.params.focal_px
        self.floor = _plane(d, np.flatnonzero(d[:, 2] < -1e-4), -cam_h, self.pix_rad)
        self.roof = _plane(d, np.flatnonzero(d[:, 2] > 1e-4), world.height_m - cam_h, self.pix_rad)
        self.floor_lv_fine = level_for(self.floor.footprint, 0.01, len(world.floor_fine.levels))
        self.floor_lv_mid = level_for(self.floor.footprint, 0.08, len(world.floor_mid.levels))
        self.roof_lv = level_for(self.roof.footprint, 0.02, len(world.roof.levels))
        ahead = math.cos(self.mount_yaw)  # the headlight at the camera shines the way it looks
        axis = np.array([ahead * math.cos(params.beam_pitch_rad), 0.0, -math.sin(params.beam_pitch_rad)])
        self.beam = (np.clip(d @ axis, 0.0, 1.0) ** params.beam_exponent).astype(np.float32)
        # Brightness falls off towards the frame's corners (a pinhole: 1 - vignette * r^2 / 2, r the
        # position in [-1, 1] across the frame) or the rim of a fisheye's image circle (1 - vignette * (angle
        # off the axis / the widest angle)^2).
        if rig.lens is None:
            u, v = np.meshgrid(np.linspace(-1, 1, w), np.linspace(-1, 1, h))
            fall = ((u**2 + v**2) / 2).reshape(-1)
        else:
            off_axis = np.arccos(np.clip(rig.rays_c.reshape(-1, 3)[:, 2], -1.0, 1.0))
            fall = (off_axis / rig.params.max_angle_rad) ** 2
        self.vignette = (1.0 - params.vignette * fall).astype(np.float32)
        self.gamma_lut = np.rint(np.power(np.linspace(0.0, 1.0, _LUT_SIZE), params.gamma) * 255.0).astype(
            np.uint8
        )

    def _cast_walls(self, ox: float, oy: float, yaw: float) -> _Walls:
        """The nearest wall segment of every azimuth bin among the segments within range."""
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
        return _Walls(seg, p0k.astype(np.float32), unit.astype(np.float32), w.wall_s0[keep])

    def radiance(self, x_m: float, y_m: float, yaw_rad: float) -> tuple[F32, F32]:
        """Linear radiance (H, W) lit by headlight and roof lights, and emission (H, W), at a pose.

        Args:
            x_m, y_m: the floor point under the camera, local metres (grid - world.origin_xy).
            yaw_rad: vehicle heading, radians CCW from +x.
        """
        pr, world = self.params, self.world
        cy, sy = np.float32(math.cos(yaw_rad)), np.float32(math.sin(yaw_rad))
        f = _Frame.empty(self.shape[0] * self.shape[1], (x_m, y_m))
        f.dirx = cy * self.cos_psi - sy * self.sin_psi
        f.diry = sy * self.cos_psi + cy * self.sin_psi
        walls = self._cast_walls(x_m, y_m, yaw_rad)
        seg = walls.seg_of_bin[self.bin_of_px]
        has_wall = seg >= 0
        seg[~has_wall] = 0
        ux, uy = walls.unit[seg, 0], walls.unit[seg, 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            rho_w = (walls.p0[seg, 0] * uy - walls.p0[seg, 1] * ux) / (f.dirx * uy - f.diry * ux)
        rho_w[~(has_wall & (rho_w > 0.01))] = np.inf
        z_w = np.float32(self.rig.params.height_m) + rho_w * self.slope
        is_wall = (z_w >= 0.0) & (z_w <= np.float32(world.height_m))
        for plane in (self.floor, self.roof):
            j = np.flatnonzero(~is_wall[plane.px] & (plane.rho < np.minimum(rho_w[plane.px], pr.max_range_m)))
            pix = plane.px[j]
            vx, vy = plane.xy[j, 0], plane.xy[j, 1]
            f.hx[pix], f.hy[pix] = cy * vx - sy * vy, sy * vx + cy * vy
            f.dist[pix], f.cos[pix] = plane.dist[j], plane.cos[j]
            if plane is self.floor:
                self._shade_floor(f, pix, j)
            else:
                self._shade_roof(f, pix, j)
        wi = np.flatnonzero(is_wall)
        if wi.size:
            self._shade_walls(f, wi, rho_w[wi], z_w[wi], seg[wi], walls)
        d_clip = np.maximum(f.dist, np.float32(pr.near_clip_m))
        light = np.float32(pr.headlight) * self.beam * f.cos / (d_clip * d_clip)
        ox, oy = np.float32(x_m), np.float32(y_m)
        light += shading.light_from_roof_lights(
            world, f.hx + ox, f.hy + oy, f.hz, f.cam, pr.light_power, pr.max_range_m
        )
        return (f.albedo * light).reshape(self.shape), f.emission.reshape(self.shape)

    def _shade_floor(self, f: _Frame, pix: NDArray[np.int64], j: NDArray[np.int64]) -> None:
        pr, world = self.params, self.world
        wx, wy = f.hx[pix] + np.float32(f.cam[0]), f.hy[pix] + np.float32(f.cam[1])
        lv = Levels.of(self.floor_lv_fine[j])
        f.albedo[pix] = shading.floor_albedo(
            world,
            wx,
            wy,
            self.floor.rho[j],
            lv,
            Levels.of(self.floor_lv_mid[j]),
            f.cam,
            pr.rut_depth,
            pr.max_range_m,
        )
        rh = self.rh[pix]
        gx, gy = world.floor_slope_x.sample(wx, wy, lv), world.floor_slope_y.sample(wx, wy, lv)
        f.cos[pix] = shading.bumped_cos(f.cos[pix], gx, gy, f.dirx[pix] * rh, f.diry[pix] * rh, pr.bump)

    def _shade_roof(self, f: _Frame, pix: NDArray[np.int64], j: NDArray[np.int64]) -> None:
        pr = self.params
        wx, wy = f.hx[pix] + np.float32(f.cam[0]), f.hy[pix] + np.float32(f.cam[1])
        f.hz[pix] = np.float32(self.world.height_m)
        f.albedo[pix], f.emission[pix] = shading.roof_albedo(
            self.world,
            wx,
            wy,
            self.roof.footprint[j],
            Levels.of(self.roof_lv[j]),
            f.cam,
            pr.light_emission,
            pr.max_range_m,
        )

    def _shade_walls(
        self, f: _Frame, wi: NDArray[np.int64], rho: F32, z: F32, k: NDArray[np.int64], walls: _Walls
    ) -> None:
        """Wall pixels ``wi`` at horizontal distance ``rho`` and height ``z`` on culled segments ``k``."""
        world, unit = self.world, walls.unit
        rh = self.rh[wi]
        dx, dy = f.dirx[wi], f.diry[wi]
        f.hx[wi], f.hy[wi], f.hz[wi] = rho * dx, rho * dy, z
        f.dist[wi] = rho / rh
        cos_flat = np.abs(unit[k, 1] * dx - unit[k, 0] * dy) * rh
        s = walls.s0[k] + (f.hx[wi] - walls.p0[k, 0]) * unit[k, 0] + (f.hy[wi] - walls.p0[k, 1]) * unit[k, 1]
        footprint = f.dist[wi] * np.float32(self.pix_rad) / np.sqrt(np.maximum(cos_flat, np.float32(0.05)))
        footprint = footprint.astype(np.float32)
        lv = Levels.for_footprint(footprint, 0.04, 3)
        f.albedo[wi] = shading.wall_albedo(world, s, z, lv, Levels.for_footprint(footprint, 0.01, 5))
        gs, gz = world.wall_slope_s.sample(s, z, lv), world.wall_slope_z.sample(s, z, lv)
        along = (dx * unit[k, 0] + dy * unit[k, 1]) * rh
        f.cos[wi] = shading.bumped_cos(cos_flat, gs, gz, along, self.slope[wi] * rh, self.params.bump)

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
        if self.seen is not None:
            sig *= self.seen
        code = (np.clip(sig, 0.0, 1.0) * np.float32(_LUT_SIZE - 1) + np.float32(0.5)).astype(np.int32)
        return np.asarray(self.gamma_lut[code].reshape(self.shape))
