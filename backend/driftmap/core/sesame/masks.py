"""SESAME: Shannon-entropy saliency masks and the salient database filter ([SESAME], sections 3.2-3.4).

A gray 8-bit image, reduced to ``R_x x R_y`` = 160 x 76 pixels (Table 1), is cut into non-overlapping
square patches of side ``Len(p)``; each patch gets its Shannon entropy over the 256 intensity bins (eq. 5)::

    H(p) = - sum_i P_p(b_i) log2 P_p(b_i),    P_p(b_i) = #{pixels of p with intensity b_i} / |p|

(the paper leaves the log base open; base 2 gives bits, at most ``log2(min(bins, |p|))``). Patches at the
right and bottom borders that do not fit a whole ``Len(p)`` are kept as smaller patches. A patch is salient
when its entropy exceeds the relative threshold ``H_min + r_threshold (H_max - H_min)`` set by the least and
most entropic patches of the image (section 3.2); a flat image (``H_max = H_min``) has no salient patch.

Hierarchical SESAME (eq. 7/10) intersects the masks of patch sizes 5, 10 and 20 px. The paper's words fix
what is intersected: "a pixel will be removed only when it lies simultaneously in plain patches of sizes 5,
10, and 20 pixels", so the *plain* (discard) masks are intersected, i.e. the salient mask is the union of the
per-scale salient masks. Masks are computed at ``R_x x R_y`` as in the paper, then resized with
nearest-neighbour to the comparison thumbnail (e.g. 64 x 32 of :class:`~driftmap.core.imaging.params.ImageParams`);
the patch sizes therefore stay in pixels of the 160 x 76 image.

The masked SAD is eq. 6 of :func:`driftmap.core.imaging.sad.sad_one_to_many` with ``mask=``. The Saliency
Score (eq. 8-9) is ``SS = sum_ij M(i, j)`` with the mask stored as an 8-bit image (salient = 255), so that
its maximum is ``SS_m = 255 R_x R_y``; ``SS / SS_m`` is the salient fraction of the image, compared with
``S_th`` = 50 %. Algorithm 1, which uses the masks and scores, is
:mod:`driftmap.core.sesame.salient_database`.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Literal

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.images import crop, downsample, to_gray
from driftmap.core.imaging.params import IMAGES_DEFAULT, ImageParams
from driftmap.core.types import F64, BoolArr
from driftmap.errors import BadInputError

__all__ = [
    "SESAME_DEFAULT",
    "SESAME_PAPER",
    "SesameParams",
    "combine_masks",
    "entropy_mask",
    "frame_saliency",
    "patch_entropy",
    "saliency_score",
    "saliency_score_max",
    "sesame_masks",
]


@dataclass(frozen=True)
class SesameParams:
    """SESAME saliency masks and map filter ([SESAME] Table 1 and sections 3.2-3.4, 4.4)."""

    mask_size_px: tuple[int, int] = (160, 76)  # (R_x, R_y): image size the entropy masks are computed at
    patch_sizes_px: tuple[int, ...] = (5, 10, 20)  # Len(p) of each mask level, pixels of mask_size_px
    bins: int = 256  # histogram bins of eq. 5 (256 intensities of an 8-bit image)
    r_threshold: float = 0.5  # relative entropy threshold in [0, 1) between the image's min and max patch
    relative_to: Literal["range", "max"] = "range"  # threshold H_min + r (H_max - H_min), or r * H_max
    min_entropy_bits: float = 0.0  # absolute floor: a patch at or below this is never salient, bits
    use_mask: bool = True  # False: every pixel is salient (plain holistic SAD)
    use_hierarchy: bool = True  # False: only the first patch size gives the mask
    adjacency_m: float = 0.5  # A_th: frames nearer than this show the same place, metres
    similarity: float = 0.25  # V_th: masked SAD below this (patch-normalised units) is the same view
    saliency_min: float = 0.5  # S_th: least SS / SS_m of a frame admitted to the database, fraction

    def __post_init__(self) -> None:
        if min(self.mask_size_px) <= 0 or not self.patch_sizes_px or min(self.patch_sizes_px) < 2:
            raise BadInputError(f"need sizes > 0 and >= 2, got {self.mask_size_px}", field="patch_sizes_px")
        if not (2 <= self.bins <= 256 and 0.0 <= self.r_threshold < 1.0):
            raise BadInputError(f"need bins in [2, 256], r in [0, 1); got {self.bins}", field="r_threshold")
        if self.relative_to not in ("range", "max"):
            raise BadInputError(f"must be range or max, got {self.relative_to!r}", field="relative_to")
        for name in ("min_entropy_bits", "adjacency_m", "similarity", "saliency_min"):
            if getattr(self, name) < 0:
                raise BadInputError(f"must be >= 0, got {getattr(self, name)}", field=name)


SESAME_PAPER = SesameParams()
# Sensor noise of a few grey levels on a blank or black frame has 1-2 bits per patch and would pass the
# relative threshold; a 2-bit floor drops it (measured: no change on simulated tunnel frames).
SESAME_DEFAULT = SesameParams(min_entropy_bits=2.0)


def _as_stack_u8(images: NDArray[np.generic], name: str) -> tuple[NDArray[np.uint8], bool]:
    arr = np.asarray(images)
    if arr.dtype != np.uint8 or arr.ndim not in (2, 3) or 0 in arr.shape:
        raise BadInputError(f"must be uint8 (H, W) or (N, H, W), got {arr.dtype} {arr.shape}", field=name)
    single = arr.ndim == 2
    return (arr[None] if single else arr), single


def patch_entropy(images: NDArray[np.uint8], patch_px: int, bins: int = 256) -> NDArray[np.float64]:
    """Shannon entropy (eq. 5) of each non-overlapping ``patch_px`` square, in bits.

    Args:
        images: ``(H, W)`` or ``(N, H, W)`` uint8 gray images.
        patch_px: patch side ``Len(p)``, pixels; border patches that do not fit are kept, smaller.
        bins: intensity bins; intensity ``v`` falls in bin ``v * bins // 256``.

    Returns:
        float64 ``(ceil(H / patch_px), ceil(W / patch_px))`` or with a leading ``N``: patch entropies in
        ``[0, log2(min(bins, patch_px**2))]`` bits.
    """
    stack, single = _as_stack_u8(images, "images")
    if patch_px < 1 or not 2 <= bins <= 256:
        raise BadInputError(f"patch_px >= 1 and bins in [2, 256], got {patch_px}, {bins}", field="patch_px")
    n, h, w = stack.shape
    ty, tx = -(-h // patch_px), -(-w // patch_px)
    tile = (np.arange(h)[:, None] // patch_px) * tx + np.arange(w)[None, :] // patch_px  # (H, W)
    # Tile-major layout, border patches padded with the out-of-range value ``bins``; sorting each patch's
    # values turns its histogram into runs, and H = log2 |p| - sum_runs c log2 c / |p| (c: run length).
    area = patch_px * patch_px
    padded = np.full((n, ty * patch_px, tx * patch_px), bins, dtype=np.uint16)
    padded[:, :h, :w] = stack.astype(np.uint16) * bins // 256
    rows = padded.reshape(n, ty, patch_px, tx, patch_px).transpose(0, 1, 3, 2, 4).reshape(-1, area)
    flat = np.sort(rows, axis=1).ravel()
    start = np.ones(flat.size, dtype=bool)
    start[1:] = flat[1:] != flat[:-1]
    start[::area] = True
    starts = np.flatnonzero(start)
    run = np.diff(np.append(starts, flat.size))
    c_log_c = np.arange(area + 1, dtype=np.float64)
    c_log_c[1:] *= np.log2(c_log_c[1:])
    weight = np.where(flat[starts] < bins, c_log_c[run], 0.0)
    sum_c_log_c = np.bincount(starts // area, weights=weight, minlength=rows.shape[0]).reshape(n, ty * tx)
    tile = (np.arange(h)[:, None] // patch_px) * tx + np.arange(w)[None, :] // patch_px  # (H, W)
    size = np.bincount(tile.ravel(), minlength=ty * tx).astype(np.float64)  # (T,) pixels per patch
    ent = np.log2(size) - sum_c_log_c / size
    ent = np.maximum(ent, 0.0).reshape(n, ty, tx)  # rounding can leave -1e-16 on a constant patch
    return np.asarray(ent[0] if single else ent, dtype=np.float64)


def entropy_mask(images: NDArray[np.uint8], patch_px: int, params: SesameParams = SESAME_DEFAULT) -> BoolArr:
    """Single-scale SESAME salient mask: pixels of patches whose entropy passes the relative threshold.

    Args:
        images: ``(H, W)`` or ``(N, H, W)`` uint8 gray images, already at the mask resolution.
        patch_px: patch side ``Len(p)``, pixels.
        params: ``bins``, ``r_threshold``, ``relative_to`` and ``min_entropy_bits``.

    Returns:
        bool, the shape of ``images``: True where the pixel lies in a salient patch.
    """
    stack, single = _as_stack_u8(images, "images")
    ent = patch_entropy(stack, patch_px, params.bins)  # (N, ty, tx)
    lo = ent.min(axis=(1, 2), keepdims=True)
    hi = ent.max(axis=(1, 2), keepdims=True)
    r = params.r_threshold
    thr = lo + r * (hi - lo) if params.relative_to == "range" else r * hi
    salient = (ent > thr) & (ent > params.min_entropy_bits)
    h, w = stack.shape[1:]
    full = np.repeat(np.repeat(salient, patch_px, axis=1), patch_px, axis=2)[:, :h, :w]
    return full[0] if single else full


def combine_masks(salient_masks: BoolArr) -> BoolArr:
    """Hierarchical combination (eq. 7/10): discard a pixel only where it is plain at every scale.

    Args:
        salient_masks: bool ``(L, ...)``, one salient mask per patch size.

    Returns:
        bool ``(...)``: ``not (plain_1 & plain_2 & ... & plain_L)``, the union of the salient masks.
    """
    m = np.asarray(salient_masks, dtype=bool)
    if m.ndim < 2 or m.shape[0] == 0:
        raise BadInputError(f"need (L, ...) masks with L >= 1, got shape {m.shape}", field="salient_masks")
    plain = np.logical_and.reduce(~m, axis=0)
    return np.asarray(~plain)


def sesame_masks(
    images: NDArray[np.generic],
    params: SesameParams = SESAME_DEFAULT,
    image_params: ImageParams | None = None,
) -> BoolArr:
    """SESAME salient masks of frames, computed at ``R_x x R_y`` and resized to the comparison thumbnail.

    The frames are converted to gray and cropped as :func:`driftmap.core.imaging.images.preprocess` does, reduced
    (INTER_AREA) to ``params.mask_size_px``, masked per scale and combined, then resized with
    nearest-neighbour to ``image_params.size_px`` so that they overlay the patch-normalised thumbnails.

    Args:
        images: ``(H, W)``, ``(N, H, W)`` or with a trailing BGR axis; uint8.
        params: mask parameters; with ``use_mask`` False every pixel is salient.
        image_params: crop and output size; None keeps the frame uncropped and returns masks at
            ``params.mask_size_px``.

    Returns:
        bool ``(h, w)`` or ``(N, h, w)``: True where the pixel is salient.
    """
    gray = to_gray(np.asarray(images))
    if image_params is not None:
        gray = crop(gray, image_params.crop_px, image_params.crop_margins_px)
    stack, single = _as_stack_u8(gray, "images")
    rx, ry = params.mask_size_px
    small = downsample(np.ascontiguousarray(stack), (rx, ry))
    sizes = params.patch_sizes_px if params.use_hierarchy else params.patch_sizes_px[:1]
    if params.use_mask:
        mask = combine_masks(np.stack([entropy_mask(small, s, params) for s in sizes]))
    else:
        mask = np.ones(small.shape, dtype=bool)
    out_size = image_params.size_px if image_params is not None and image_params.size_px else (rx, ry)
    mask = _resize_nearest(mask, out_size)
    return np.asarray(mask[0] if single else mask)


def _resize_nearest(masks: BoolArr, size_px: tuple[int, int]) -> BoolArr:
    """``(N, H, W)`` bool masks resized with nearest-neighbour to ``size_px = (w, h)``."""
    if masks.shape[-2:] == (size_px[1], size_px[0]):
        return masks
    u8 = masks.astype(np.uint8)
    return np.stack([cv2.resize(m, tuple(size_px), interpolation=cv2.INTER_NEAREST) for m in u8]) > 0


def saliency_score(masks: BoolArr) -> F64:
    """Saliency Score SS (eq. 8): the sum of the 8-bit mask image (salient pixels = 255).

    Args:
        masks: bool ``(H, W)`` or ``(N, H, W)`` salient masks at ``R_x x R_y``.

    Returns:
        float64 ``()`` or ``(N,)``: SS, at most :func:`saliency_score_max` of the mask size.
    """
    m = np.asarray(masks, dtype=bool)
    if m.ndim not in (2, 3):
        raise BadInputError(f"must be (H, W) or (N, H, W), got shape {m.shape}", field="masks")
    return np.asarray(255.0 * m.sum(axis=(-2, -1)), dtype=np.float64)


def saliency_score_max(size_px: tuple[int, int]) -> float:
    """``SS_m = 255 R_x R_y`` (eq. 9) for a mask of ``size_px = (R_x, R_y)`` pixels."""
    return 255.0 * size_px[0] * size_px[1]


def frame_saliency(
    images: NDArray[np.generic],
    params: SesameParams = SESAME_DEFAULT,
    image_params: ImageParams = IMAGES_DEFAULT,
) -> tuple[F64, BoolArr]:
    """Everything SESAME needs of a stack of frames: ``SS / SS_m`` at ``R_x x R_y`` and the thumbnail masks.

    Args:
        images: ``(N, H, W)`` uint8 gray frames (or ``(N, H, W, 3)`` BGR).
        params: mask parameters.
        image_params: crop and thumbnail size of the compared images.

    Returns:
        ``(saliency, masks)``: float64 ``(N,)`` salient fraction ``SS / SS_m`` (eq. 8-9) in [0, 1], and
        bool ``(N, h, w)`` masks at ``image_params.size_px`` (``R_x x R_y`` when that is None).
    """
    full = sesame_masks(images, params, replace(image_params, size_px=None))
    if full.ndim != 3:
        raise BadInputError(f"need a stack (N, H, W), got shape {np.shape(images)}", field="images")
    saliency = saliency_score(full) / saliency_score_max(params.mask_size_px)
    return saliency, _resize_nearest(full, image_params.size_px or params.mask_size_px)
