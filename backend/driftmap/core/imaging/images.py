"""Image pre-processing for place recognition ([SSLAM], section IV-C).

Every frame is converted to grayscale, cropped, down-sampled and patch normalised before it is
compared with the SAD of :mod:`driftmap.core.imaging.sad`. Patch normalisation subtracts from each pixel
the mean of the square patch centred on it and divides by that patch's standard deviation, which
removes slow changes of brightness and contrast (lighting, exposure) and keeps local texture.

All functions take a single image ``(H, W)`` or a stack ``(N, H, W)``; colour input may carry a
trailing channel axis ``(..., H, W, 3|4)`` (OpenCV BGR order) for :func:`to_gray` only.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.params import ImageParams

__all__ = ["crop", "downsample", "mask_pyramid", "patch_normalise", "preprocess", "pyramid", "to_gray"]


def _check_gray(images: NDArray, name: str) -> None:
    if images.ndim not in (2, 3) or images.shape[-1] == 0 or images.shape[-2] == 0:
        raise ValueError(f"{name} must be (H, W) or (N, H, W) with H, W > 0, got shape {images.shape}")


def to_gray(images: NDArray) -> NDArray:
    """Convert an image or a stack to single-channel grayscale.

    Args:
        images: ``(H, W)`` or ``(N, H, W)`` already gray (returned unchanged), or colour
            ``(H, W, C)`` / ``(N, H, W, C)`` with C = 3 (BGR) or 4 (BGRA); any dtype OpenCV accepts
            (uint8, uint16, float32).

    Returns:
        ``(H, W)`` or ``(N, H, W)``, same dtype as the input.

    Raises:
        ValueError: an unsupported shape.
    """
    images = np.asarray(images)
    if images.ndim == 2:
        return images
    if images.ndim == 3 and images.shape[-1] not in (3, 4):
        return images  # a gray stack (N, H, W)
    if images.ndim in (3, 4) and images.shape[-1] in (3, 4):
        code = cv2.COLOR_BGR2GRAY if images.shape[-1] == 3 else cv2.COLOR_BGRA2GRAY
        if images.ndim == 3:
            return np.asarray(cv2.cvtColor(images, code))
        return np.stack([cv2.cvtColor(im, code) for im in images])
    raise ValueError(
        f"images must be (H, W), (N, H, W) or with a trailing 3/4 channel axis, got {images.shape}"
    )


def crop(
    images: NDArray,
    rect_px: tuple[int, int, int, int] | None = None,
    margins_px: tuple[int, int, int, int] | None = None,
) -> NDArray:
    """Crop an image or stack to a rectangle, or by margins; a view, no copy.

    Args:
        images: ``(H, W)`` or ``(N, H, W)``, any dtype.
        rect_px: ``(x, y, w, h)`` pixels: keep columns ``x:x+w`` and rows ``y:y+h``.
        margins_px: ``(left, top, right, bottom)`` pixels to remove. Give at most one of the two;
            with neither the input is returned.

    Returns:
        ``(h, w)`` or ``(N, h, w)`` view of ``images``.

    Raises:
        ValueError: both arguments given, or the rectangle does not fit inside the image.
    """
    images = np.asarray(images)
    _check_gray(images, "images")
    height, width = images.shape[-2:]
    if rect_px is not None and margins_px is not None:
        raise ValueError("give rect_px or margins_px, not both")
    if margins_px is not None:
        left, top, right, bottom = margins_px
        rect_px = (left, top, width - left - right, height - top - bottom)
    if rect_px is None:
        return images
    x, y, w, h = (int(v) for v in rect_px)
    if x < 0 or y < 0 or w <= 0 or h <= 0 or x + w > width or y + h > height:
        raise ValueError(f"crop rectangle {(x, y, w, h)} does not fit a {width}x{height} image")
    return images[..., y : y + h, x : x + w]


def downsample(images: NDArray, size_px: tuple[int, int]) -> NDArray:
    """Resize an image or stack to ``size_px`` with area averaging (``cv2.INTER_AREA``).

    Args:
        images: ``(H, W)`` or ``(N, H, W)``; uint8, uint16 or float32.
        size_px: target ``(width, height)`` in pixels.

    Returns:
        ``(height, width)`` or ``(N, height, width)``, same dtype as the input.

    Raises:
        ValueError: a bad shape or non-positive size.
    """
    images = np.asarray(images)
    _check_gray(images, "images")
    w, h = (int(v) for v in size_px)
    if w <= 0 or h <= 0:
        raise ValueError(f"size_px must be positive, got {size_px}")
    if images.shape[-2:] == (h, w):
        return images
    if images.ndim == 2:
        return np.asarray(cv2.resize(images, (w, h), interpolation=cv2.INTER_AREA))
    out = np.empty((images.shape[0], h, w), dtype=images.dtype)
    for i, im in enumerate(images):
        out[i] = cv2.resize(im, (w, h), interpolation=cv2.INTER_AREA)
    return out


def patch_normalise(images: NDArray, patch_px: int = 8, min_std: float = 1e-3) -> NDArray[np.float32]:
    """Subtract each pixel's local patch mean and divide by the local patch standard deviation.

    The patch is the ``patch_px`` x ``patch_px`` square centred on the pixel (for even sizes the
    pixel sits just right/below the centre); borders are reflected. Means and variances come from
    box filters, so the cost is O(pixels) whatever the patch size. Where the local standard
    deviation is below ``min_std`` (a flat patch) the output is 0, never NaN or inf.

    Args:
        images: ``(H, W)`` or ``(N, H, W)``, any real dtype (typically uint8 0-255).
        patch_px: side of the square patch, pixels, >= 2.
        min_std: standard deviation (in input intensity units) below which a patch counts as flat.

    Returns:
        float32 array of the input's shape: dimensionless, about zero mean and unit variance on
        textured images.

    Raises:
        ValueError: a bad shape or patch size.
    """
    images = np.asarray(images)
    _check_gray(images, "images")
    if patch_px < 2:
        raise ValueError(f"patch_px must be >= 2, got {patch_px}")
    if images.ndim == 3:
        out = np.empty(images.shape, dtype=np.float32)
        for i, im in enumerate(images):
            out[i] = _patch_normalise_one(im, patch_px, min_std)
        return out
    return _patch_normalise_one(images, patch_px, min_std)


def _patch_normalise_one(image: NDArray, patch_px: int, min_std: float) -> NDArray[np.float32]:
    """Patch normalisation of one ``(H, W)`` image; see :func:`patch_normalise`."""
    img = image.astype(np.float32)
    img -= np.float32(img.mean())  # centring keeps E[x^2] - E[x]^2 well conditioned in float32
    ksize = (patch_px, patch_px)
    border = cv2.BORDER_REFLECT_101 if min(img.shape) > patch_px // 2 else cv2.BORDER_REPLICATE
    mean = np.asarray(cv2.boxFilter(img, cv2.CV_32F, ksize, normalize=True, borderType=border), np.float32)
    std = np.asarray(
        cv2.boxFilter(img * img, cv2.CV_32F, ksize, normalize=True, borderType=border), np.float32
    )
    # std holds E[x^2]; in place, the operations of (img - mean) / sqrt(max(E[x^2] - mean^2, 0))
    std -= mean * mean
    np.maximum(std, np.float32(0.0), out=std)
    np.sqrt(std, out=std)
    flat = std < np.float32(min_std)
    std[flat] = 1.0
    img -= mean
    img /= std
    img[flat] = 0.0
    return img


def preprocess(images: NDArray, params: ImageParams) -> NDArray[np.float32]:
    """The IV-C chain: grayscale, crop, down-sample, patch normalise.

    Args:
        images: one frame ``(H, W)`` / ``(H, W, 3)`` or a stack ``(N, H, W)`` / ``(N, H, W, 3)``.
        params: the crop, target size and patch size.

    Returns:
        float32 ``(h, w)`` or ``(N, h, w)`` with ``(w, h) = params.size_px`` (or the cropped size
        when ``size_px`` is None).
    """
    gray = to_gray(images)
    gray = crop(gray, params.crop_px, params.crop_margins_px)
    if params.size_px is not None:
        gray = downsample(np.ascontiguousarray(gray), params.size_px)
    return patch_normalise(gray, params.patch_px, params.min_std)


def pyramid(image: NDArray, levels: int) -> list[NDArray[np.float32]]:
    """Gaussian pyramid ``[level 0 = image, level 1 = half size, ...]`` via ``cv2.pyrDown``.

    Args:
        image: ``(H, W)`` any real dtype.
        levels: number of halvings (>= 0); level ``l`` pixel ``i`` sits at level-0 pixel ``2^l i``.

    Returns:
        ``levels + 1`` float32 arrays.
    """
    img = np.asarray(image, dtype=np.float32)
    if img.ndim != 2:
        raise ValueError(f"image must be (H, W), got {img.shape}")
    out = [img]
    for _ in range(levels):
        out.append(np.asarray(cv2.pyrDown(out[-1]), dtype=np.float32))
    return out


def mask_pyramid(mask: NDArray, levels: int) -> list[NDArray[np.float32]]:
    """Pyramid of a {0, 1} mask: a coarse pixel is 1 only when its whole footprint is 1."""
    return [(m >= 0.999).astype(np.float32) for m in pyramid(np.asarray(mask, dtype=np.float32), levels)]
