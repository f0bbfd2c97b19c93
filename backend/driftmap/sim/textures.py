"""Procedural, seeded, tileable textures and their mip-mapped sampling.

Textures are float32 albedo images in [0, 1], periodic in both directions (made with FFT-filtered
noise, so every tile wraps seamlessly). A :class:`MipTexture` is sampled with world coordinates in
metres: texel ``i`` of level ``l`` covers [i, i + 1) * texel_m * 2**l. Sampling uses ``cv2.remap``
(bilinear); a level per sample picks the pyramid level whose texels match the pixel footprint, which
keeps distant surfaces from sparkling.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "F32",
    "Levels",
    "MipTexture",
    "floor_fine_texture",
    "floor_mid_texture",
    "level_for",
    "periodic_noise",
    "remap_linear",
    "roof_texture",
    "sample_by_level",
    "slopes",
    "wall_fine_texture",
    "wall_relief",
]

F32 = NDArray[np.float32]
_REMAP_ROW = 1024  # cv2.remap wants maps narrower than SHRT_MAX: sample in rows of this length


def remap_linear(img: NDArray[Any], x: F32, y: F32, border: int = cv2.BORDER_REPLICATE) -> F32:
    """Bilinear samples of ``img`` (H, W) at float pixel positions ``x, y`` (N,) -> (N,) float32."""
    n = x.size
    if n == 0:
        return np.zeros(0, np.float32)
    m = -(-n // _REMAP_ROW) * _REMAP_ROW
    mx = np.zeros(m, np.float32)
    my = np.zeros(m, np.float32)
    mx[:n] = x
    my[:n] = y
    out = cv2.remap(
        img, mx.reshape(-1, _REMAP_ROW), my.reshape(-1, _REMAP_ROW), cv2.INTER_LINEAR, borderMode=border
    )
    return np.asarray(out.reshape(-1)[:n], dtype=np.float32)


def periodic_noise(rng: np.random.Generator, h: int, w: int, beta: float, cutoff: float = 0.5) -> F32:
    """Tileable 1/f^beta noise (H, W), zero mean, unit standard deviation.

    Args:
        rng: source of randomness.
        h, w: size in texels.
        beta: spectral exponent of the amplitude (larger: smoother).
        cutoff: highest kept frequency in cycles per texel (0.5 keeps all).
    """
    white = rng.standard_normal((h, w))
    fy = np.fft.fftfreq(h)[:, None]
    fx = np.fft.rfftfreq(w)[None, :]
    f = np.hypot(fx, fy)
    f[0, 0] = 1.0
    gain = f ** (-beta) * (f <= cutoff)
    gain[0, 0] = 0.0
    out = np.fft.irfft2(np.fft.rfft2(white) * gain, s=(h, w))
    return np.asarray((out - out.mean()) / max(float(out.std()), 1e-12), dtype=np.float32)


def _blobs(rng: np.random.Generator, h: int, w: int, count: int, radius_px: float) -> F32:
    """Tileable field of ``count`` soft round bumps of random sign and height, about ``radius_px`` wide."""
    impulses = np.zeros((h, w))
    iy, ix = rng.integers(0, h, count), rng.integers(0, w, count)
    np.add.at(impulses, (iy, ix), rng.uniform(-1.0, 1.0, count))
    fy = np.fft.fftfreq(h)[:, None]
    fx = np.fft.rfftfreq(w)[None, :]
    kernel = np.exp(-2.0 * (np.pi * radius_px) ** 2 * (fx**2 + fy**2))  # FT of a Gaussian of sigma r
    out = np.fft.irfft2(np.fft.rfft2(impulses) * kernel, s=(h, w))
    return np.asarray(out / max(float(np.abs(out).max()), 1e-12), dtype=np.float32)


@dataclass(frozen=True, eq=False)
class MipTexture:
    """A tileable texture and its pyramid, sampled with coordinates in metres (wraps around)."""

    levels: tuple[F32, ...]  # level l has (H / 2**l + 1, W / 2**l + 1): the last row/column repeat the first
    texel_m: float  # size of a level-0 texel

    @staticmethod
    def build(img: F32, texel_m: float, n_levels: int) -> MipTexture:
        """Pyramid of ``img`` (H, W), both divisible by 2**(n_levels - 1), with wrap-around padding."""
        levels = []
        cur = np.asarray(img, dtype=np.float32)
        for level in range(n_levels):
            if level:
                cur = 0.25 * (cur[0::2, 0::2] + cur[1::2, 0::2] + cur[0::2, 1::2] + cur[1::2, 1::2])
            levels.append(np.ascontiguousarray(np.pad(cur, ((0, 1), (0, 1)), mode="wrap")))
        return MipTexture(tuple(levels), texel_m)

    @property
    def period_m(self) -> tuple[float, float]:
        """(along u, along v) repeat distance in metres."""
        h, w = self.levels[0].shape
        return (w - 1) * self.texel_m, (h - 1) * self.texel_m

    def sample_level(self, u_m: F32, v_m: F32, level: int) -> F32:
        """Samples (N,) at positions (N,) metres from pyramid level ``level``."""
        level = min(max(level, 0), len(self.levels) - 1)
        img = self.levels[level]
        h, w = img.shape[0] - 1, img.shape[1] - 1
        inv_t = np.float32(1.0 / (self.texel_m * (1 << level)))
        x = u_m * inv_t
        y = v_m * inv_t
        x -= np.floor(x * np.float32(1.0 / w)) * np.float32(w) + np.float32(0.5)
        y -= np.floor(y * np.float32(1.0 / h)) * np.float32(h) + np.float32(0.5)
        x[x < 0] += w
        y[y < 0] += h
        return remap_linear(img, x, y)

    def sample(self, u_m: F32, v_m: F32, levels: Levels) -> F32:
        """Samples (N,) at positions (N,) metres, each from the pyramid level of its group."""
        return sample_by_level(self.sample_level, u_m, v_m, levels)


@dataclass(frozen=True, eq=False)
class Levels:
    """Sample indices grouped by pyramid level, computed once and shared by every texture sampled at
    the same points (a group's indices are None when it holds all samples)."""

    groups: tuple[tuple[int, NDArray[np.int64] | None], ...]
    n: int

    @staticmethod
    def of(level: NDArray[np.int8]) -> Levels:
        """Group (N,) levels."""
        if level.size == 0:
            return Levels((), 0)
        counts = np.bincount(level)
        present = np.flatnonzero(counts)
        if len(present) == 1:
            return Levels(((int(present[0]), None),), level.size)
        order = np.argsort(level, kind="stable")
        bounds = np.cumsum(counts)
        return Levels(
            tuple((int(lv), order[bounds[lv] - counts[lv] : bounds[lv]]) for lv in present), level.size
        )

    @staticmethod
    def for_footprint(footprint_m: F32, texel_m: float, n_levels: int) -> Levels:
        """Group samples by the level whose texels match their pixel footprints (metres)."""
        return Levels.of(level_for(footprint_m, texel_m, n_levels))


def sample_by_level(fn: Callable[[F32, F32, int], F32], u: F32, v: F32, levels: Levels) -> F32:
    """Apply a single-level sampler ``fn`` to the samples of each level group."""
    if len(levels.groups) == 1 and levels.groups[0][1] is None:
        return fn(u, v, levels.groups[0][0])
    out = np.empty(u.shape, np.float32)
    for lv, idx in levels.groups:
        assert idx is not None
        out[idx] = fn(u[idx], v[idx], lv)
    return out


def level_for(footprint_m: F32, texel_m: float, n_levels: int) -> NDArray[np.int8]:
    """Pyramid level whose texel best matches a pixel footprint (metres), (N,) int8."""
    lv = np.floor(np.log2(np.maximum(footprint_m, 1e-6) / texel_m) + 0.5)
    return np.clip(lv, 0, n_levels - 1).astype(np.int8)


# -------------------------------------------------------------------------------------- the texture set


def floor_fine_texture(rng: np.random.Generator, size: int = 1024) -> tuple[F32, F32]:
    """Gravel and fines at 1 cm texels: (albedo, height in metres), stones of 1-6 cm over dust.

    Stones stand up to ~1.5 cm proud of the fines; their height drives the bump shading that makes
    them cast light and shade under the headlight.
    """
    base = 0.35 * periodic_noise(rng, size, size, 1.2)
    stones = (
        0.9 * _blobs(rng, size, size, 9000, 1.2)
        + 0.9 * _blobs(rng, size, size, 2500, 2.5)
        + 0.7 * _blobs(rng, size, size, 500, 5.0)
    )
    shape = np.tanh(2.5 * stones)
    img = 0.5 + 0.12 * base + 0.42 * shape
    height = 0.008 * shape + 0.002 * base
    return np.asarray(np.clip(img, 0.02, 1.0), dtype=np.float32), np.asarray(height, dtype=np.float32)


def slopes(height_m: F32, texel_m: float) -> tuple[F32, F32]:
    """Periodic central-difference slopes (d/du, d/dv) of a tileable height field (metres per metre)."""
    gu = (np.roll(height_m, -1, axis=1) - np.roll(height_m, 1, axis=1)) / (2 * texel_m)
    gv = (np.roll(height_m, -1, axis=0) - np.roll(height_m, 1, axis=0)) / (2 * texel_m)
    return np.asarray(gu, dtype=np.float32), np.asarray(gv, dtype=np.float32)


def wall_relief(rng: np.random.Generator, rows: int = 128, cols: int = 2048) -> F32:
    """Height (metres, towards the tunnel) of blasted rock at 4 cm texels: blocks and overbreak of
    0.2-4 m, +-10 cm, and drill half-barrels (grooves along the wall)."""
    h = 0.06 * periodic_noise(rng, rows, cols, 1.7) + 0.012 * periodic_noise(rng, rows, cols, 1.0)
    for _ in range(cols // 40):
        r, c0, length = (
            int(rng.integers(20, rows - 10)),
            int(rng.integers(0, cols)),
            int(rng.integers(40, 95)),
        )
        idx = (c0 + np.arange(length)) % cols
        h[r - 1 : r + 2, idx] -= np.array([[0.01], [0.025], [0.01]])
    return np.asarray(h, dtype=np.float32)


def floor_mid_texture(rng: np.random.Generator, size: int = 1024) -> F32:
    """Slow brightness changes of the floor at 8 cm texels (wet patches, spilled fines), mean ~1."""
    n = periodic_noise(rng, size, size, 1.6)
    wet = np.clip(periodic_noise(rng, size, size, 2.2) - 1.2, 0.0, None)
    return np.asarray(np.clip(1.0 + 0.22 * n - 0.35 * wet, 0.3, 1.6), dtype=np.float32)


def wall_fine_texture(rng: np.random.Generator, w: int = 1024, h: int = 512) -> F32:
    """Rock grain at 1 cm texels (u: along the wall, v: height), mean ~1 (multiplies the strip)."""
    n = 0.6 * periodic_noise(rng, h, w, 1.5) + 0.5 * _blobs(rng, h, w, 6000, 2.0)
    return np.asarray(np.clip(1.0 + 0.22 * n, 0.4, 1.6), dtype=np.float32)


def roof_texture(rng: np.random.Generator, size: int = 1024) -> F32:
    """Shotcrete with welded mesh and bolt plates at 2 cm texels (20 m tile), mean ~0.45."""
    img = 0.45 + 0.08 * periodic_noise(rng, size, size, 1.3) + 0.06 * periodic_noise(rng, size, size, 2.2)
    grid = np.zeros((size, size), np.float32)
    grid[::5, :] = 1.0  # 10 cm mesh
    grid[:, ::5] = 1.0
    img -= 0.10 * grid
    pitch = 64  # 1.28 m bolt pattern
    for y in range(pitch // 2, size, pitch):
        for x in range(pitch // 2, size, pitch):
            dy, dx = rng.integers(-6, 7, 2)
            cv2.rectangle(
                img, (int(x + dx - 4), int(y + dy - 4)), (int(x + dx + 4), int(y + dy + 4)), 0.75, -1
            )
    return np.asarray(np.clip(img, 0.02, 1.0), dtype=np.float32)
