"""Place recognition on outside datasets: single-image SAD / SESAME matching and the HMM over a route.

A place-recognition dataset is a set of reference (database) images, in route order, and a set of query
images. Both are reduced to patch-normalised thumbnails (:func:`driftmap.core.imaging.images.preprocess`) whose
height follows the input's aspect ratio ([SESAME] section 4.6 keeps it unchanged), then:

* ``sad`` compares every query with every reference by the shifted, overlap-normalised SAD of
  :mod:`driftmap.core.imaging.sad` ([SSLAM] eq. 3): a ``(Q, D)`` distance matrix, computed in cache-sized blocks.
* ``sesame`` applies [SESAME]: the query's hierarchical entropy mask (eq. 5, 7, 10) restricts the SAD to
  its salient pixels, normalised by their count (eq. 6), and reference images whose Saliency Score
  ``SS / SS_m`` (eq. 8-9) is below ``S_th`` are left out of the database (section 3.4: mostly dark or bright
  references otherwise become the best match of many queries). Algorithm 1's adjacency test needs metric
  positions, which a plain dataset folder lacks, so only its saliency threshold applies here.

With ``temporal`` the reference images form a route and :mod:`driftmap.core.place_recognition.route` runs an HMM over the
chain of references on the distance rows of the query images, taken in order (smoothed over all of them by
default, or causally).

Single-image scores are the distinctness ``1 - d_best / median_j d(i, j)`` of the best match (0 when it is
no better than a typical reference, towards 1 when it stands out), as the localiser's single-image mode.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.images import preprocess
from driftmap.core.imaging.params import SAD_DEFAULT, ImageParams, SadParams
from driftmap.core.imaging.sad import sad_one_to_many
from driftmap.core.sesame import masks as saliency
from driftmap.core.types import F32, I64, BoolArr
from driftmap.errors import BadInputError

__all__ = [
    "METHODS",
    "VPR_DEFAULT",
    "VPR_PRESETS",
    "VPR_ROUTE",
    "Matches",
    "PreparedImages",
    "VprMethod",
    "VprParams",
    "check_pair",
    "distance_matrix",
    "match_single",
    "prepare_images",
    "thumbnail_params",
]

VprMethod = Literal["sad", "sesame"]
METHODS: tuple[VprMethod, ...] = ("sad", "sesame")


@dataclass(frozen=True)
class VprParams:
    """How images of a place-recognition dataset are compared: thumbnails, SAD shift search, SESAME."""

    thumb_width_px: int = 64  # thumbnail width; the height keeps the input's aspect ratio (64x32 for 2:1)
    patch_px: int = 8  # patch-normalisation square, thumbnail pixels ([SSLAM] IV-C)
    mask_width_px: int = 160  # SESAME mask width R_x (Table 1), never above the input's; R_y keeps the aspect
    sad: SadParams = SAD_DEFAULT  # shift search of the SAD
    sesame: saliency.SesameParams = (
        saliency.SESAME_DEFAULT
    )  # entropy masks; saliency_min is S_th of section 3.4

    def __post_init__(self) -> None:
        if self.thumb_width_px < 8 or self.mask_width_px < 8:
            raise BadInputError("must be >= 8 pixels", field="thumb_width_px")
        if self.patch_px < 2:
            raise BadInputError(f"must be >= 2, got {self.patch_px}", field="patch_px")


#: The mine's comparison ([SSLAM] IV-C): 64-pixel-wide thumbnails, shifts +-4 / +-2 px for lateral offsets.
VPR_DEFAULT = VprParams()
#: A camera that keeps to one path (rail, corridor centreline, road lane): no shift search. Measured on the
#: outside data: on the corridor the +-4/+-2 search changes no match; on Nordland it only adds false matches
#: (route HMM AUC 0.81 without shifts, 0.70 with +-4/0) at 9-45x the cost.
VPR_ROUTE = VprParams(sad=SadParams(max_shift_x_px=0, max_shift_y_px=0))
VPR_PRESETS: dict[str, VprParams] = {"mine": VPR_DEFAULT, "route": VPR_ROUTE}


@dataclass(frozen=True, eq=False)
class PreparedImages:
    """Images reduced for matching.

    Attributes:
        thumbs: ``(N, h, w)`` float32 patch-normalised thumbnails.
        masks: bool ``(N, h, w)`` SESAME salient masks on the thumbnails, or None (method ``sad``).
        saliency: ``(N,)`` float64 ``SS / SS_m`` in [0, 1], or None (method ``sad``).
        usable: ``(N,)`` bool: salient enough (``SS / SS_m > S_th``) to serve as a reference; all True
            without SESAME.
    """

    thumbs: F32
    masks: BoolArr | None
    saliency: NDArray[np.float64] | None
    usable: BoolArr


@dataclass(frozen=True, eq=False)
class Matches:
    """The best reference of each query.

    Attributes:
        db_index: ``(Q,)`` int64 index of the best reference in route order.
        score: ``(Q,)`` float64 confidence, higher = better (distinctness, or the HMM belief).
    """

    db_index: I64
    score: NDArray[np.float64]


def _aspect_size(shape_hw: tuple[int, int], width_px: int) -> tuple[int, int]:
    height, width = shape_hw
    w = min(width_px, width)
    return w, max(2, round(w * height / width))


def thumbnail_params(shape_hw: tuple[int, int], params: VprParams = VPR_DEFAULT) -> ImageParams:
    """Pre-processing of images of ``shape_hw = (H, W)`` pixels: aspect-preserving thumbnail, patch size."""
    return ImageParams(size_px=_aspect_size(shape_hw, params.thumb_width_px), patch_px=params.patch_px)


def prepare_images(
    images: NDArray[np.uint8], method: VprMethod, params: VprParams = VPR_DEFAULT
) -> PreparedImages:
    """Thumbnails (and SESAME masks and saliency) of a stack of images.

    Args:
        images: ``(N, H, W)`` uint8 grey images, all the same size.
        method: ``sad`` (thumbnails only) or ``sesame`` (also masks and ``SS / SS_m``).
        params: thumbnail and mask sizes, SESAME parameters.

    Returns:
        :class:`PreparedImages`.

    Raises:
        BadInputError: not a uint8 ``(N, H, W)`` stack, or an unknown method.
    """
    imgs = np.asarray(images)
    if imgs.dtype != np.uint8 or imgs.ndim != 3 or 0 in imgs.shape:
        raise BadInputError(f"need uint8 (N, H, W) images, got {imgs.dtype} {imgs.shape}", field="images")
    if method not in METHODS:
        raise BadInputError(f"unknown method {method!r}; choose {', '.join(METHODS)}", field="method")
    shape_hw = (int(imgs.shape[1]), int(imgs.shape[2]))
    image_params = thumbnail_params(shape_hw, params)
    thumbs = preprocess(imgs, image_params)
    if method == "sad":
        return PreparedImages(thumbs, None, None, np.ones(thumbs.shape[0], dtype=bool))
    sesame = replace(params.sesame, mask_size_px=_aspect_size(shape_hw, params.mask_width_px))
    sal, masks = saliency.frame_saliency(imgs, sesame, image_params)
    return PreparedImages(thumbs, masks, sal, np.asarray(sal > params.sesame.saliency_min))


def check_pair(query: PreparedImages, db: PreparedImages) -> None:
    if query.thumbs.shape[1:] != db.thumbs.shape[1:]:
        raise BadInputError(
            f"query thumbnails {query.thumbs.shape[1:]} and reference thumbnails {db.thumbs.shape[1:]} differ:"
            " query and db images must have the same aspect ratio (images narrower than the thumbnail keep"
            " their size)",
            field="query",
        )
    if (query.masks is None) != (db.saliency is None):
        raise BadInputError("query and db must be prepared with the same method", field="method")


def distance_matrix(
    query: PreparedImages, db: PreparedImages, params: VprParams = VPR_DEFAULT, *, workers: int = 1
) -> F32:
    """Difference scores of every query against every reference ([SSLAM] eq. 3; [SESAME] eq. 6).

    Each row streams the references through :func:`driftmap.core.imaging.sad.sad_one_to_many` in cache-sized chunks
    (with the query's salient mask for SESAME); rows are shared among ``workers`` threads (OpenCV and BLAS
    release the GIL).

    Args:
        query: prepared query images, ``Q`` of them.
        db: prepared reference images, ``D`` of them, same thumbnail size and method.
        params: the SAD shift search.
        workers: threads computing rows.

    Returns:
        ``(Q, D)`` float32 mean absolute difference at the best shift (patch-normalised units); ``inf`` for
        references left out of the database (SESAME saliency below ``S_th``) and where nothing overlaps.
    """
    check_pair(query, db)
    usable = db.usable
    refs = np.ascontiguousarray(db.thumbs[usable])  # gathered once, not once per row
    out = np.full((query.thumbs.shape[0], usable.size), np.inf, dtype=np.float32)
    if refs.shape[0] == 0:
        return out

    def row(i: int) -> None:
        mask = None if query.masks is None else query.masks[i].astype(np.float32)
        out[i, usable] = sad_one_to_many(query.thumbs[i], refs, params.sad, mask).d

    if workers <= 1:
        for i in range(query.thumbs.shape[0]):
            row(i)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(row, range(query.thumbs.shape[0])))
    return out


def match_single(d: F32) -> Matches:
    """Best reference per query of a ``(Q, D)`` distance matrix and its distinctness score.

    Returns:
        :class:`Matches`: ``argmin_j d(i, j)`` and ``1 - d_best / median of the finite d(i, .)`` (0 when the
        row has no finite score).
    """
    d = np.asarray(d, dtype=np.float32)
    if d.ndim != 2 or 0 in d.shape:
        raise BadInputError(f"need a (Q, D) matrix, got shape {d.shape}", field="d")
    finite = np.isfinite(d)
    filled = np.where(finite, d, np.inf)
    best = np.argmin(filled, axis=1).astype(np.int64)
    d_best = filled[np.arange(d.shape[0]), best].astype(np.float64)
    med = np.nanmedian(np.where(finite, d, np.nan).astype(np.float64), axis=1) if finite.any() else d_best
    ok = np.isfinite(d_best) & np.isfinite(med) & (med > 0)
    score = np.zeros(d.shape[0], dtype=np.float64)
    score[ok] = 1.0 - d_best[ok] / med[ok]
    return Matches(db_index=best, score=score)
