"""The wall strip: one long texture over (arc length along the walls, height) for the whole site.

Every wall ring is unrolled onto a common arc-length axis ``s`` (rings separated by a gap), so a wall
point has texture coordinates (s, z). The strip holds what is particular to a place: bare rock or
shotcrete, stains, blast rounds, cables, vent ducts, signs, doors, brows. Fine rock grain is added by a
separate tiled texture at render time.

Storage: 4 cm texels, 128 rows (5.12 m), cut into blocks of 4096 columns stacked vertically (OpenCV's
remap only takes images narrower than 32767 pixels). Each block has one padding row below and above
and one extra column copied from the next block, so bilinear sampling never crosses a seam. Values
are uint8 albedo scaled by ``scale / 255`` (retro-reflective paint can exceed 1).

A wall is seen from inside the tunnel with increasing ``s`` running to the viewer's left (rings are
oriented with the tunnel on their left), so patches are pasted mirrored to read correctly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from driftmap.sim.textures import F32, Levels, periodic_noise, remap_linear, sample_by_level

__all__ = ["BLOCK_COLS", "ROWS", "TEXEL_M", "Patch", "StripAtlas", "StripBuilder"]

TEXEL_M = 0.04  # strip texel, metres
ROWS = 128  # rows of level 0 (5.12 m)
BLOCK_COLS = 4096  # columns of a level-0 block
N_LEVELS = 3  # 4, 8 and 16 cm
SCALE = 1.6  # albedo of value 255


@dataclass(frozen=True)
class Patch:
    """A picture pasted on the wall: ``img`` (rows top-down, columns left-to-right as seen)."""

    s_m: float  # arc length of the patch's left edge as seen by a viewer (its larger-s end)
    z_m: float  # height of its bottom edge
    img: F32  # (h, w) albedo
    alpha: F32 | None = None  # (h, w) opacity in [0, 1]; None = opaque


@dataclass(frozen=True, eq=False)
class StripAtlas:
    """The folded, mip-mapped strip; sample it with :meth:`sample`."""

    levels: tuple[NDArray[np.uint8], ...]  # level l: (n_blocks * (ROWS/2^l + 2), BLOCK_COLS/2^l + 1)
    n_blocks: int

    def sample_level(self, s_m: F32, z_m: F32, level: int) -> F32:
        """Albedo at wall coordinates (N,) metres from pyramid ``level``, (N,) float32."""
        level = min(max(level, 0), N_LEVELS - 1)
        t = TEXEL_M * (1 << level)
        rows, cols = ROWS >> level, BLOCK_COLS >> level
        x = np.maximum(s_m * np.float32(1.0 / t) - np.float32(0.5), np.float32(0.0))
        b = np.minimum(np.floor(x / cols), self.n_blocks - 1)
        y = np.clip(z_m * np.float32(1.0 / t) - np.float32(0.5), -0.5, rows - 0.5)
        xs = (x - b * cols).astype(np.float32)
        ys = (b * (rows + 2) + 1 + y).astype(np.float32)
        img = self.levels[level]
        return remap_linear(img, xs, ys) * np.float32(SCALE / 255.0)

    def sample(self, s_m: F32, z_m: F32, levels: Levels) -> F32:
        """Albedo at (N,) wall coordinates, each from the level of its group (0 = 4 cm texels)."""
        return sample_by_level(self.sample_level, s_m, z_m, levels)


@dataclass
class StripBuilder:
    """Collects per-column properties and patches, then renders the atlas block by block."""

    total_m: float  # arc length covered
    rng: np.random.Generator
    n_cols: int = 0
    brightness: F32 = field(default_factory=lambda: np.zeros(0, np.float32))  # base albedo per column
    aliased: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))  # periodic template
    cable: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))  # cables hang here
    duct: NDArray[np.bool_] = field(default_factory=lambda: np.zeros(0, bool))  # vent duct here
    patches: list[Patch] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.n_cols = math.ceil(self.total_m / TEXEL_M) + 2
        self.brightness = np.full(self.n_cols, 0.45, np.float32)
        self.aliased = np.zeros(self.n_cols, bool)
        self.cable = np.zeros(self.n_cols, bool)
        self.duct = np.zeros(self.n_cols, bool)

    def cols(self, s0_m: float, s1_m: float) -> slice:
        """The columns covering arc lengths [s0, s1)."""
        a = int(np.clip(math.floor(min(s0_m, s1_m) / TEXEL_M), 0, self.n_cols))
        b = int(np.clip(math.ceil(max(s0_m, s1_m) / TEXEL_M), 0, self.n_cols))
        return slice(a, b)

    def build(self) -> StripAtlas:
        """Render every block; returns the folded atlas with its pyramid."""
        n_blocks = math.ceil(self.n_cols / BLOCK_COLS)
        rng = self.rng
        tile_a = self._rock_tile(rng, 4096, 1.4, half_barrels=True)
        tile_b = self._rock_tile(rng, 3001, 1.9, half_barrels=False)
        template = self._rock_tile(rng, 300, 1.6, half_barrels=True)
        rounds = self._rounds(rng)
        stains = np.clip(periodic_noise(rng, 1, 8192, 1.0)[0] - 0.9, 0.0, None)
        z = (np.arange(ROWS, dtype=np.float32) + 0.5) * TEXEL_M
        z_profile = (0.8 + 0.2 * np.clip(z / 1.2, 0.0, 1.0)).astype(np.float32)[:, None]
        patches = sorted(self.patches, key=lambda p: p.s_m)
        starts = np.array([p.s_m - p.img.shape[1] * TEXEL_M for p in patches])
        ends = np.array([p.s_m for p in patches])
        blocks: list[list[NDArray[np.uint8]]] = [[] for _ in range(N_LEVELS)]
        for b in range(n_blocks):
            c = np.arange(b * BLOCK_COLS, (b + 1) * BLOCK_COLS)
            cc = np.minimum(c, self.n_cols - 1)
            rock = 0.5 * (tile_a[:, c % 4096] + tile_b[:, (c * 7 + 13) % 3001])
            rock = np.where(self.aliased[cc][None, :], template[:, c % 300], rock)
            stain = np.where(self.aliased[cc], 0.0, stains[c % 8192])[None, :] * (z[:, None] / 5.0)
            img = (
                self.brightness[cc][None, :]
                * z_profile
                * (1.0 + 0.45 * rock)
                * rounds[c % rounds.size][None, :]
            )
            img = img * (1.0 - 0.8 * stain)
            self._services(img, c, cc, z)
            lo, hi = b * BLOCK_COLS * TEXEL_M, (b + 1) * BLOCK_COLS * TEXEL_M
            for i in np.flatnonzero((starts < hi) & (ends > lo)):
                self._paste(img, b, patches[int(i)])
            for level in range(N_LEVELS):
                q = np.clip(np.rint(img * (255.0 / SCALE)), 0, 255).astype(np.uint8)
                blocks[level].append(q)
                img = 0.25 * (img[0::2, 0::2] + img[1::2, 0::2] + img[0::2, 1::2] + img[1::2, 1::2])
        levels = []
        for level in range(N_LEVELS):
            padded = []
            for b, blk in enumerate(blocks[level]):
                nxt = blocks[level][b + 1][:, :1] if b + 1 < n_blocks else blk[:, -1:]
                blk = np.concatenate([blk, nxt], axis=1)
                padded.append(np.concatenate([blk[:1], blk, blk[-1:]], axis=0))
            levels.append(np.ascontiguousarray(np.concatenate(padded, axis=0)))
        return StripAtlas(tuple(levels), n_blocks)

    # ---------------------------------------------------------------------------------------- content

    @staticmethod
    def _rock_tile(rng: np.random.Generator, cols: int, beta: float, half_barrels: bool) -> F32:
        """(ROWS, cols) periodic rock relief in about [-1, 1]; optional drill half-barrels along s."""
        tile = 0.5 * periodic_noise(rng, ROWS, cols, beta)
        if half_barrels:
            for _ in range(cols // 60):
                r = int(rng.integers(30, ROWS - 10))
                c0 = int(rng.integers(0, cols))
                length = int(rng.integers(40, 95))
                idx = (c0 + np.arange(length)) % cols
                tile[r, idx] -= 1.3
                tile[r + 1, idx] += 0.5
        return np.asarray(np.clip(tile, -1.5, 1.5), dtype=np.float32)

    @staticmethod
    def _rounds(rng: np.random.Generator) -> F32:
        """Per-column factor marking blast rounds every ~3.8 m (a darker, slightly ragged line)."""
        n = 50_000
        f = np.ones(n, np.float32)
        c = 0
        while c < n:
            c += int(rng.integers(85, 105))
            f[c % n] = 0.6
            f[(c + 1) % n] = 0.8
        return f

    def _services(self, img: F32, c: NDArray[np.int64], cc: NDArray[np.int64], z: F32) -> None:
        """Cables (sagging between hangers every 2.5 m) and a vent duct, in place on one block."""
        cable_cols = np.flatnonzero(self.cable[cc])
        if cable_cols.size:
            frac = ((c[cable_cols] * TEXEL_M) % 2.5) / 2.5
            sag = 0.12 * (1.0 - (2.0 * frac - 1.0) ** 2)
            for z0 in (3.55, 3.75, 3.9):
                zc = z0 - sag
                near = np.abs(z[:, None] - zc[None, :]) < 0.035
                img[:, cable_cols] = np.where(near, 0.06, img[:, cable_cols])
        duct_cols = np.flatnonzero(self.duct[cc])
        if duct_cols.size:
            band = (z >= 4.05) & (z <= 4.85)
            seam = ((c[duct_cols] * TEXEL_M) % 10.0) < 0.12
            shade = 0.95 - 0.35 * np.abs((z[band] - 4.45) / 0.4) ** 2
            val = np.where(seam[None, :], 0.3, shade[:, None])
            rows = np.flatnonzero(band)
            img[rows[:, None], duct_cols[None, :]] = val

    @staticmethod
    def _paste(img: F32, block: int, p: Patch) -> None:
        """Paste patch ``p`` (mirrored: viewer's right = decreasing s) into block ``block``."""
        h, w = p.img.shape
        src = p.img[::-1, ::-1]  # rows bottom-up, columns in increasing s
        alpha = None if p.alpha is None else p.alpha[::-1, ::-1]
        c0 = round(p.s_m / TEXEL_M) - w - block * BLOCK_COLS
        r0 = round(p.z_m / TEXEL_M)
        a0, a1 = max(c0, 0), min(c0 + w, BLOCK_COLS)
        b0, b1 = max(r0, 0), min(r0 + h, ROWS)
        if a0 >= a1 or b0 >= b1:
            return
        part = src[b0 - r0 : b1 - r0, a0 - c0 : a1 - c0]
        if alpha is None:
            img[b0:b1, a0:a1] = part
        else:
            al = alpha[b0 - r0 : b1 - r0, a0 - c0 : a1 - c0]
            img[b0:b1, a0:a1] = al * part + (1.0 - al) * img[b0:b1, a0:a1]
