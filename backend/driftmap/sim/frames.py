"""Rendering work units: chunks of consecutive frames of one drive, rendered and PNG-encoded.

A worker process holds one :class:`~driftmap.sim.render.Renderer` (set by :func:`init_worker`) and
turns a :class:`Chunk` into PNG bytes: the clean frame and, for localisation drives, its obscured
copies. Everything random is seeded by (site seed, drive, frame), so chunks can run anywhere in any
order and give identical bytes.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from driftmap.processes import end_with_parent
from driftmap.sim.geometry import FloatArray
from driftmap.sim.obscurants import LEVELS, apply_level
from driftmap.sim.render import Renderer
from driftmap.sim.ride import apply_ride

__all__ = ["Chunk", "encode_png", "exposure_curve", "init_worker", "render_chunk"]

_PNG_PARAMS = [
    cv2.IMWRITE_PNG_COMPRESSION,
    1,
    cv2.IMWRITE_PNG_STRATEGY,
    cv2.IMWRITE_PNG_STRATEGY_RLE,
]  # fast, small for noisy frames
_worker: dict[str, Renderer] = {}


@dataclass(frozen=True, eq=False)
class Chunk:
    """Frames ``start .. start + len(poses) - 1`` of drive number ``drive``."""

    drive: int
    start: int
    last: bool  # the drive's final chunk
    seed: int  # site seed
    poses: FloatArray  # (n, 3) local x, y (metres, grid - world origin), yaw (radians)
    exposure: FloatArray  # (n,) exposure gain
    ride: FloatArray  # (n, 4) camera pitch, roll and mount yaw (radians), vertical motion blur (pixels)
    variants: tuple[tuple[str, str, tuple[float, float] | None], ...]  # (suffix, level, water centre)


def init_worker(renderer: Renderer) -> None:
    """Install the renderer of this process."""
    _worker["renderer"] = renderer


def init_pool_worker(renderer: Renderer) -> None:
    """Pool initializer: install the renderer; end this process when the simulation's process is gone."""
    init_worker(renderer)
    end_with_parent()


def encode_png(img: np.ndarray) -> bytes:
    ok, buf = cv2.imencode(".png", img, _PNG_PARAMS)
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return bytes(buf.tobytes())


def render_chunk(chunk: Chunk) -> dict[str, list[bytes]]:
    """PNG bytes of every frame of ``chunk``: key "" for the clean frames, then one key per variant."""
    r = _worker["renderer"]
    out: dict[str, list[bytes]] = {"": []}
    for name, _, _ in chunk.variants:
        out[name] = []
    for k, (x, y, yaw) in enumerate(chunk.poses):
        frame = chunk.start + k
        img = r.render(
            float(x), float(y), float(yaw), float(chunk.exposure[k]), [chunk.seed, 71, chunk.drive, frame]
        )
        pitch, roll, yaw_mount, blur = chunk.ride[k]
        img = apply_ride(img, r.rig, float(pitch), float(roll), float(yaw_mount), float(blur))
        out[""].append(encode_png(img))
        for name, level, centre in chunk.variants:
            rng = np.random.default_rng([chunk.seed, 73, chunk.drive, frame, list(LEVELS).index(level)])
            out[name].append(encode_png(apply_level(img, LEVELS[level], rng, centre)))
    return out


def exposure_curve(t_s: FloatArray, rng: np.random.Generator) -> FloatArray:
    """Auto-exposure gain over time (n,): slow drift of +-25 % around a per-drive base level.

    Sums four sinusoids with periods of 6-60 s and random phases, so the gain changes smoothly
    from frame to frame but brightness differs between drives and between passes of a place.
    """
    base = rng.uniform(0.85, 1.15)
    drift = np.zeros_like(t_s)
    for _ in range(4):
        period = rng.uniform(6.0, 60.0)
        drift += np.sin(2 * np.pi * t_s / period + rng.uniform(0, 2 * np.pi))
    return np.asarray(base * np.exp(0.12 * drift))
