"""Simulated camera obscurants of [SSLAM], section IV-A: aerosolised dust and water on the lens.

* Dust level 1 / 2: 5 % / 10 % of the pixels of every frame, chosen at random per frame, set to grey.
* Water level 1 / 2: a static circular region of 90 / 150 pixels diameter at the paper's 944x800
  resolution, blurred with a Gaussian; the same circle in every frame of a drive.

Water diameters are scaled to the frame by its width: ``d_px = d_paper_px * width_px / 944`` (at
320x240 that is 30.5 and 50.8 px). The blur's sigma is a quarter of the diameter, so the region is
washed out (as a drop on the lens is) without pixels outside the circle changing.

Images are uint8 ``(H, W)`` grayscale or ``(H, W, C)`` colour; every function returns a new array.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "LEVELS",
    "PAPER_WIDTH_PX",
    "ObscurantLevel",
    "apply_dust",
    "apply_level",
    "apply_water",
    "water_centre",
    "water_diameter_px",
    "water_mask",
]

PAPER_WIDTH_PX = 944  # frame width of the paper's camera (944x800)
DUST_GREY = 128  # the grey that dust pixels are set to


@dataclass(frozen=True)
class ObscurantLevel:
    """One obscurant level of the paper's study."""

    name: str  # "dust1", "dust2", "water1" or "water2"
    kind: Literal["dust", "water"]
    dust_fraction: float = 0.0  # fraction of pixels set to grey per frame (dust)
    water_diameter_paper_px: float = 0.0  # blurred circle diameter at 944 px width (water)


LEVELS: dict[str, ObscurantLevel] = {
    "dust1": ObscurantLevel("dust1", "dust", dust_fraction=0.05),
    "dust2": ObscurantLevel("dust2", "dust", dust_fraction=0.10),
    "water1": ObscurantLevel("water1", "water", water_diameter_paper_px=90.0),
    "water2": ObscurantLevel("water2", "water", water_diameter_paper_px=150.0),
}


def _check_image(img: NDArray[np.uint8]) -> None:
    if img.dtype != np.uint8 or img.ndim not in (2, 3) or img.shape[0] == 0 or img.shape[1] == 0:
        raise ValueError(f"expected a uint8 (H, W) or (H, W, C) image, got {img.dtype} {img.shape}")


def apply_dust(
    img: NDArray[np.uint8], fraction: float, rng: np.random.Generator, grey: int = DUST_GREY
) -> NDArray[np.uint8]:
    """Set ``round(fraction * H * W)`` distinct random pixels to ``grey`` (all channels).

    Args:
        img: (H, W) or (H, W, C) uint8 frame.
        fraction: share of pixels in [0, 1].
        rng: draws the pixels; seed it per frame for a new pattern each frame.
        grey: the dust value, 0-255.
    """
    _check_image(img)
    if not 0.0 <= fraction <= 1.0:
        raise ValueError(f"dust fraction must lie in [0, 1], got {fraction}")
    h, w = img.shape[:2]
    count = round(fraction * h * w)
    out = img.copy()
    idx = rng.choice(h * w, size=count, replace=False)
    out.reshape(h * w, -1)[idx] = grey
    return out


def water_diameter_px(diameter_paper_px: float, width_px: int) -> float:
    """A paper water diameter (at 944 px width) scaled to a frame ``width_px`` wide."""
    return diameter_paper_px * width_px / PAPER_WIDTH_PX


def water_centre(shape: tuple[int, ...], diameter_px: float, rng: np.random.Generator) -> tuple[float, float]:
    """A random centre (x, y) in pixels keeping the whole circle inside a frame of ``shape`` (H, W, ...)."""
    h, w = shape[:2]
    r = diameter_px / 2
    if 2 * r > min(h, w):
        raise ValueError(f"a water drop of {diameter_px:.1f} px does not fit a {w}x{h} frame")
    return float(rng.uniform(r, w - 1 - r)), float(rng.uniform(r, h - 1 - r))


def water_mask(
    shape: tuple[int, ...], diameter_px: float, centre_xy: tuple[float, float]
) -> NDArray[np.bool_]:
    """(H, W) mask of the pixels whose centres lie inside the circle."""
    h, w = shape[:2]
    yy, xx = np.mgrid[0:h, 0:w]
    r = diameter_px / 2
    return np.asarray((xx - centre_xy[0]) ** 2 + (yy - centre_xy[1]) ** 2 <= r * r)


def apply_water(
    img: NDArray[np.uint8], diameter_px: float, centre_xy: tuple[float, float], sigma_px: float | None = None
) -> NDArray[np.uint8]:
    """Blur the circle of ``diameter_px`` at ``centre_xy`` (pixels) with a Gaussian; nothing else changes.

    Args:
        img: (H, W) or (H, W, C) uint8 frame.
        diameter_px: circle diameter in pixels of this frame (see :func:`water_diameter_px`).
        centre_xy: circle centre (x, y) in pixels; keep it fixed for a whole drive.
        sigma_px: Gaussian sigma; default a quarter of the diameter.
    """
    _check_image(img)
    if diameter_px <= 0:
        raise ValueError(f"water diameter must be positive, got {diameter_px}")
    sigma = diameter_px / 4 if sigma_px is None else sigma_px
    h, w = img.shape[:2]
    # blur only the circle's box plus a margin the kernel (radius 3 sigma, as OpenCV sizes it for
    # 8-bit images) cannot cross, so the values equal those of blurring the whole frame
    reach = diameter_px / 2 + 1
    x0, x1 = max(int(centre_xy[0] - reach), 0), min(int(centre_xy[0] + reach) + 1, w)
    y0, y1 = max(int(centre_xy[1] - reach), 0), min(int(centre_xy[1] + reach) + 1, h)
    pad = math.ceil(3 * sigma) + 1
    px0, px1, py0, py1 = max(x0 - pad, 0), min(x1 + pad, w), max(y0 - pad, 0), min(y1 + pad, h)
    blurred = cv2.GaussianBlur(img[py0:py1, px0:px1], (0, 0), sigma, borderType=cv2.BORDER_REFLECT)
    mask = water_mask((y1 - y0, x1 - x0), diameter_px, (centre_xy[0] - x0, centre_xy[1] - y0))
    out = img.copy()
    window = out[y0:y1, x0:x1]
    window[mask] = blurred[y0 - py0 : y1 - py0, x0 - px0 : x1 - px0][mask]
    return out


def apply_level(
    img: NDArray[np.uint8],
    level: ObscurantLevel,
    frame_rng: np.random.Generator,
    centre_xy: tuple[float, float] | None = None,
) -> NDArray[np.uint8]:
    """Apply one paper level: dust with ``frame_rng``, or water at ``centre_xy`` (required for water)."""
    if level.kind == "dust":
        return apply_dust(img, level.dust_fraction, frame_rng)
    if centre_xy is None:
        raise ValueError("water needs the drive's fixed centre_xy")
    return apply_water(img, water_diameter_px(level.water_diameter_paper_px, img.shape[1]), centre_xy)
