"""Parameters of the image pre-processing and the shifted SAD, with their presets.

Presets follow the rule of :mod:`driftmap.core`: ``<STAGE>_PAPER`` follows the papers as closely as they
say, ``<STAGE>_DEFAULT`` is what driftmap uses, ``<STAGE>_FAST`` trades accuracy for speed. Units are in the
field names (``_px``, ``_m``, ``_rad``) or comments.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "IMAGES_DEFAULT",
    "IMAGES_FAST",
    "IMAGES_PAPER",
    "SAD_DEFAULT",
    "SAD_FAST",
    "SAD_PAPER",
    "ImageParams",
    "SadParams",
]


@dataclass(frozen=True)
class ImageParams:
    """Place-recognition pre-processing ([SSLAM] IV-C): gray, crop, down-sample, patch normalise."""

    crop_px: tuple[int, int, int, int] | None = None  # (x, y, w, h) kept before down-sampling; None keeps all
    crop_margins_px: tuple[int, int, int, int] | None = None  # (left, top, right, bottom) removed instead
    size_px: tuple[int, int] | None = (64, 32)  # (width, height) after INTER_AREA down-sampling; None keeps
    patch_px: int = 8  # side of the patch-normalisation square, pixels of the down-sampled image
    min_std: float = 1e-3  # local std (input intensity units) below which a patch is flat and outputs 0

    def __post_init__(self) -> None:
        if self.crop_px is not None and self.crop_margins_px is not None:
            raise ValueError("ImageParams: give crop_px or crop_margins_px, not both")
        if self.size_px is not None and min(self.size_px) <= 0:
            raise ValueError(f"ImageParams.size_px must be positive, got {self.size_px}")
        if self.patch_px < 2:
            raise ValueError(f"ImageParams.patch_px must be >= 2, got {self.patch_px}")


@dataclass(frozen=True)
class SadParams:
    """Shifted SAD image comparison ([SSLAM] eq. 3/4; masked form of [SESAME] eq. 6)."""

    max_shift_x_px: int = 4  # lateral search +-x_max, pixels of the compared images
    max_shift_y_px: int = 2  # vertical search +-y_max, pixels
    chunk_bytes: int = 1 << 20  # bound on float32 temporaries per chunk; ~L2-cache sized is fastest

    def __post_init__(self) -> None:
        if self.max_shift_x_px < 0 or self.max_shift_y_px < 0:
            raise ValueError("SadParams: shifts must be >= 0")
        if self.chunk_bytes < 1024:
            raise ValueError("SadParams.chunk_bytes must be >= 1024")


IMAGES_PAPER = ImageParams(size_px=(64, 32), patch_px=8)
IMAGES_DEFAULT = IMAGES_PAPER
IMAGES_FAST = ImageParams(size_px=(32, 24), patch_px=4)

SAD_PAPER = SadParams(max_shift_x_px=4, max_shift_y_px=2)
SAD_DEFAULT = SAD_PAPER
SAD_FAST = SadParams(max_shift_x_px=2, max_shift_y_px=1)
