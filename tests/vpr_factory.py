"""Images for place-recognition tests: textured places that survive noise, and noisy views of them."""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

U8 = NDArray[np.uint8]


def textures(n: int, seed: int = 0, shape: tuple[int, int] = (32, 64)) -> U8:
    """(n, H, W) uint8 grey textures, distinct per place, smooth enough to survive noise."""
    rng = np.random.default_rng(seed)
    raw = rng.normal(0.0, 1.0, (n, *shape)).astype(np.float32)
    out = np.stack([np.asarray(cv2.GaussianBlur(r, (0, 0), 1.2), dtype=np.float32) for r in raw])
    out = 128 + 40 * out / out.std(axis=(1, 2), keepdims=True)
    return np.asarray(np.clip(out, 0, 255), dtype=np.uint8)


def noisy(images: U8, sigma: float, seed: int) -> U8:
    """The images plus Gaussian noise of ``sigma`` grey levels, clipped to uint8."""
    rng = np.random.default_rng(seed)
    return np.clip(images + rng.normal(0.0, sigma, images.shape), 0, 255).astype(np.uint8)
