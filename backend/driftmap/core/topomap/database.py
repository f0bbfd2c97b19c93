"""The localisation database of a map: which mapping frames each node keeps ([SESAME], 3.4-3.5, Algorithm 1).

Each node of the topological map stores reference frames that queries are compared with ([SSLAM] eq. 4:
the node score is the minimum over them). Paper 001 builds that database with SESAME:

1. **Quality filter** (3.5): a linear SVM (:mod:`driftmap.core.sesame.glare_svm`) trained on artificial glare images
   and stitched good images made from the site's own frames drops glare-struck frames. The training
   sources are ``quality_sources`` frames spread evenly over the mapping drives, taken among the more
   salient half of a regular sample (typical, clean scenes, as the paper hand-picks them).
2. **BuildSalientDatabase** (Algorithm 1, :mod:`driftmap.core.sesame.salient_database`): of frames
   nearer than A_th that look alike (masked SAD below V_th), only the most salient is kept, and a frame
   whose salient fraction SS/SS_m is below S_th is never admitted.
3. **Per node**, the kept frames are taken most salient first, skipping a frame within ``view_spacing_m``
   of an already chosen frame facing the same way (within 90 degrees), up to ``frames_per_node``. Nodes are
   5 m long, so this keeps a view about every metre in each travel direction, which is what lets a query
   taken between two nodes' centres find a close reference.

A node whose frames all fail a filter keeps its best frames anyway (the filter is skipped for it), so no
place of the map becomes unreachable. :func:`database_selector` returns the ``FrameSelector`` that
:func:`driftmap.core.topomap.build.build_topomap` calls with every node; :func:`salient_frame_selector` is the
paper's selector alone (Algorithm 1 on each node's frames, then the k most salient).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.images import downsample
from driftmap.core.imaging.params import IMAGES_DEFAULT, SAD_DEFAULT, ImageParams, SadParams
from driftmap.core.sesame.glare_svm import (
    QUALITY_DEFAULT,
    QualityClassifier,
    QualityParams,
    quality_features,
    train_quality_classifier,
)
from driftmap.core.sesame.masks import SESAME_DEFAULT, SESAME_PAPER, SesameParams, frame_saliency
from driftmap.core.sesame.salient_database import PairScores, build_salient_databases
from driftmap.core.topomap.model import FrameSelector, NodeFrames, select_frames_by_heading, wrap_rad
from driftmap.core.types import F64, I64
from driftmap.errors import BadInputError

__all__ = [
    "DATABASE_DEFAULT",
    "DATABASE_OFF",
    "DATABASE_PAPER",
    "DatabaseParams",
    "FrameStats",
    "FrameStatsPass",
    "database_selector",
    "finish_frame_stats",
    "frame_stats",
    "salient_frame_selector",
]

STATS_CHUNK = 128  # frames processed together (a drive segment starts on a multiple of it)
_SOURCE_CANDIDATES = 4  # regular sample of this many times quality_sources frames; the salient half is used
_PER_FRAME = ("chain", "row", "frame_id", "xy_m", "yaw_rad", "dist_m", "quality", "visit")


@dataclass(frozen=True)
class DatabaseParams:
    """How each node's reference frames are chosen ([SESAME] Table 1 for the SESAME thresholds)."""

    use_sesame: bool = True  # Algorithm 1 and saliency-ordered views; False: the topomap's default selector
    use_quality: bool = True  # drop frames the glare classifier calls bad
    sesame: SesameParams = SESAME_DEFAULT  # masks, A_th, V_th, S_th
    quality: QualityParams = QUALITY_DEFAULT  # synthetic training data and SVM
    quality_sources: int = 20  # clean frames the classifier's synthetic images are made from (paper: 20)
    seed: int = 0  # seeds the classifier's synthetic data
    frames_per_node: int = 12  # most reference frames kept per node with SESAME on
    view_spacing_m: float = 1.0  # least distance between two chosen frames facing the same way, metres

    def __post_init__(self) -> None:
        if self.quality_sources < 2 or self.frames_per_node < 1 or not self.view_spacing_m >= 0:
            raise BadInputError(
                "need quality_sources >= 2, frames_per_node >= 1, view_spacing_m >= 0",
                field="frames_per_node",
            )

    @property
    def enabled(self) -> bool:
        """Whether any part of the database filter is on."""
        return self.use_sesame or self.use_quality


DATABASE_PAPER = DatabaseParams(sesame=SESAME_PAPER)
DATABASE_DEFAULT = DatabaseParams()
DATABASE_OFF = DatabaseParams(use_sesame=False, use_quality=False)


@dataclass(frozen=True, eq=False)
class FrameStats:
    """What the database selector needs of every mapping frame (flat index over the drives in order).

    Attributes:
        saliency: (F,) float64 salient fraction SS / SS_m (eq. 8-9), in [0, 1].
        masks: (F, h, w) bool SESAME masks at the thumbnail size.
        good: (F,) bool quality-classifier verdicts (all True when the filter is off).
        classifier: the trained classifier, or None when the filter is off.
    """

    saliency: F64
    masks: NDArray[np.bool_]
    good: NDArray[np.bool_]
    classifier: QualityClassifier | None

    @property
    def rejected_fraction(self) -> float:
        """Fraction of frames the quality classifier rejected."""
        return float(1.0 - self.good.mean()) if self.good.size else 0.0


class FrameStatsPass:
    """The per-frame half of :func:`frame_stats` over one drive, fed frame by frame.

    Lets the map build compute the statistics in the odometry's pass over a drive (frames decoded
    once, drives in parallel); :func:`finish_frame_stats` then trains the classifier. Frames are
    processed in chunks of ``STATS_CHUNK`` per drive, as :func:`frame_stats` does, so results are the same.

    Args:
        offset: flat index of the drive's first frame over all mapping drives.
        total: frames of all mapping drives, F (sets the classifier's sampling stride).
        params: database parameters (SESAME masks, classifier).
        image_params: crop and thumbnail size of the compared images.
    """

    def __init__(
        self, offset: int, total: int, params: DatabaseParams, image_params: ImageParams = IMAGES_DEFAULT
    ) -> None:
        self.params, self.image_params = params, image_params
        self.stride = max(1, total // (_SOURCE_CANDIDATES * params.quality_sources))
        self.seen = offset  # flat index of the next frame
        self.frames = 0  # frames of this drive so far
        self.sal: list[F64] = []
        self.masks: list[NDArray[np.bool_]] = []
        self.feats: list[F64] = []
        self.sample: list[NDArray] = []
        self.sample_sal: list[F64] = []
        self._batch: list[NDArray[np.uint8]] = []

    def add(self, frame: NDArray[np.uint8]) -> None:
        """Take the drive's next ``(H, W)`` uint8 grey frame."""
        self._batch.append(frame)
        if len(self._batch) == STATS_CHUNK:
            self._flush()

    def close(self) -> FrameStatsPass:
        """Process the last partial chunk; returns ``self``."""
        if self._batch:
            self._flush()
        return self

    def _flush(self) -> None:
        chunk = np.stack(self._batch)
        self._batch = []
        s, m = frame_saliency(chunk, self.params.sesame, self.image_params)
        self.sal.append(s)
        self.masks.append(m)
        if self.params.use_quality:
            self.feats.append(quality_features(chunk, self.params.quality))
            pick = np.flatnonzero((self.seen + np.arange(chunk.shape[0])) % self.stride == 0)
            self.sample.append(
                downsample(np.ascontiguousarray(chunk[pick]), self.params.quality.feature_size_px)
            )
            self.sample_sal.append(s[pick])
        self.seen += chunk.shape[0]
        self.frames += chunk.shape[0]


def frame_stats(
    drives: Sequence[Callable[[], Iterable[NDArray[np.uint8]]]],
    counts: Sequence[int],
    params: DatabaseParams = DATABASE_DEFAULT,
    image_params: ImageParams = IMAGES_DEFAULT,
) -> FrameStats:
    """Saliency, masks and quality verdicts of every frame of the mapping drives (one pass over the frames).

    Args:
        drives: per drive, a callable returning a fresh iterator over its (H, W) uint8 grey frames.
        counts: per drive, its number of frames N_d.
        params: database parameters (SESAME masks, classifier).
        image_params: crop and thumbnail size of the compared images.

    Returns:
        :class:`FrameStats` over the F = sum N_d frames.
    """
    if len(drives) != len(counts):
        raise BadInputError("one frame count per drive is required", field="counts")
    total = int(sum(counts))
    passes = []
    offset = 0
    for source, count in zip(drives, counts, strict=True):
        stats = FrameStatsPass(offset, total, params, image_params)
        for frame in source():
            stats.add(frame)
        passes.append(stats.close())
        offset += count
    return finish_frame_stats(passes, counts, params, image_params)


def finish_frame_stats(
    passes: Sequence[FrameStatsPass],
    counts: Sequence[int],
    params: DatabaseParams = DATABASE_DEFAULT,
    image_params: ImageParams = IMAGES_DEFAULT,
) -> FrameStats:
    """:class:`FrameStats` of the drives' closed passes (in drive order): trains the quality classifier.

    Args:
        passes: per drive, its :class:`FrameStatsPass` after ``close()``.
        counts: per drive, its number of frames N_d (checked against the frames the pass saw).
        params: database parameters (as given to the passes).
        image_params: crop and thumbnail size (as given to the passes).

    Raises:
        BadInputError: a drive gave another number of frames than its count.
    """
    for stats, count in zip(passes, counts, strict=True):
        if stats.frames != count:
            raise BadInputError(f"a drive gave {stats.frames} frames, expected {count}", field="counts")
    total = int(sum(counts))
    sal = [s for p in passes for s in p.sal]
    masks = [m for p in passes for m in p.masks]
    h, w = (image_params.size_px or params.sesame.mask_size_px)[::-1]
    sal_all = np.concatenate(sal) if sal else np.zeros(0)
    mask_all = np.concatenate(masks) if masks else np.zeros((0, h, w), dtype=bool)
    good = np.ones(total, dtype=bool)
    classifier = None
    if params.use_quality and total:
        candidates = np.concatenate([c for p in passes for c in p.sample])
        cand_sal = np.concatenate([c for p in passes for c in p.sample_sal])
        salient = np.flatnonzero(cand_sal >= np.median(cand_sal))
        take = salient[
            np.linspace(0, salient.size - 1, min(params.quality_sources, salient.size)).astype(int)
        ]
        classifier = train_quality_classifier(candidates[take], params.seed, params.quality)
        z = (
            np.concatenate([f for p in passes for f in p.feats]) - classifier.feature_mean
        ) / classifier.feature_scale
        good = np.asarray(z @ classifier.coef + classifier.intercept > 0)
    return FrameStats(sal_all, mask_all, good, classifier)


def _spaced_by_saliency(cands: NodeFrames, rows: I64, sal: F64, k: int, spacing_m: float) -> I64:
    """Up to ``k`` of ``rows``, most salient first, none within ``spacing_m`` of a chosen one facing alike."""
    order = rows[np.argsort(-sal, kind="stable")]
    chosen: list[int] = []
    for r in order.tolist():
        if len(chosen) == k:
            break
        if chosen:
            near = np.linalg.norm(cands.xy_m[chosen] - cands.xy_m[r], axis=1) < spacing_m
            alike = np.abs(wrap_rad(cands.yaw_rad[chosen] - cands.yaw_rad[r])) < math.pi / 2
            if np.any(near & alike):
                continue
        chosen.append(r)
    return np.asarray(chosen, dtype=np.int64)


def database_selector(
    stats: FrameStats,
    thumbs_by_flat_frame: NDArray[np.float32],
    chain_ptr: I64,
    params: DatabaseParams = DATABASE_DEFAULT,
    sad_params: SadParams = SAD_DEFAULT,
    scores: PairScores | None = None,
) -> FrameSelector:
    """The topomap ``FrameSelector`` of the SESAME database (see the module docstring).

    Args:
        stats: per-frame saliency, masks and quality verdicts (:func:`frame_stats`).
        thumbs_by_flat_frame: (F, h, w) float32 patch-normalised thumbnails, flat frame order.
        chain_ptr: (chains + 1,) int64 first flat frame of each chain.
        params: database parameters; the selector returns at most ``min(k, frames_per_node)`` frames.
        sad_params: SAD shift ranges of Algorithm 1's similarity test.
        scores: Algorithm 1's pair scores known from an earlier build, flat frame indices (see
            :class:`~driftmap.core.sesame.salient_database.PairScores`); records the pairs compared.

    Returns:
        ``(nodes, k) -> per node (<= k,) int64`` rows of its frames (never empty for a node with frames);
        Algorithm 1 runs on all the nodes together
        (:func:`~driftmap.core.sesame.salient_database.build_salient_databases`).
    """
    thumbs = np.asarray(thumbs_by_flat_frame, dtype=np.float32)
    ptr = np.asarray(chain_ptr, dtype=np.int64)
    n = stats.saliency.shape[0]
    if thumbs.shape[0] != n or stats.masks.shape != thumbs.shape or ptr[-1] != n:
        raise BadInputError(
            f"stats of {n} frames, thumbs {thumbs.shape}, masks {stats.masks.shape} disagree", field="stats"
        )

    def select(nodes: Sequence[NodeFrames], k: int) -> list[I64]:
        member_rows = []
        for cands in nodes:
            flat = ptr[cands.chain] + cands.row
            rows = np.lexsort((cands.row, cands.chain)).astype(np.int64)  # time order within each drive
            if params.use_quality and stats.good[flat[rows]].any():
                rows = rows[stats.good[flat[rows]]]
            member_rows.append(rows)
        if not params.use_sesame:
            picks = []
            for cands, rows in zip(nodes, member_rows, strict=True):
                sub = NodeFrames(cands.node, cands.centre_m, *(getattr(cands, a)[rows] for a in _PER_FRAME))
                picks.append(np.asarray(rows[select_frames_by_heading(sub, k)], dtype=np.int64))
            return picks
        flats = [(ptr[c.chain] + c.row)[rows] for c, rows in zip(nodes, member_rows, strict=True)]
        kept = build_salient_databases(
            flats,
            [c.xy_m[rows] for c, rows in zip(nodes, member_rows, strict=True)],
            stats.saliency,
            thumbs,
            stats.masks,
            params.sesame,
            sad_params,
            scores,
        )
        limit = min(k, params.frames_per_node)
        picks = []
        for cands, rows, flat, keep in zip(nodes, member_rows, flats, kept, strict=True):
            if keep.size:
                rows, flat = rows[keep], flat[keep]
            picks.append(_spaced_by_saliency(cands, rows, stats.saliency[flat], limit, params.view_spacing_m))
        return picks

    return select


def salient_frame_selector(
    saliency_scores_by_flat_frame: F64,
    thumbs_by_flat_frame: NDArray[np.float32],
    chain_ptr: I64,
    masks_by_flat_frame: NDArray[np.bool_] | None = None,
    good_by_flat_frame: NDArray[np.bool_] | None = None,
    params: SesameParams = SESAME_DEFAULT,
    sad_params: SadParams = SAD_DEFAULT,
) -> FrameSelector:
    """A topomap ``FrameSelector`` running Algorithm 1 on each node's frames, then keeping the k most salient.

    Args:
        saliency_scores_by_flat_frame: ``(F,)`` float64 ``SS / SS_m`` per flat frame (chains concatenated
            in :func:`~driftmap.core.topomap.build.build_topomap` input order).
        thumbs_by_flat_frame: ``(F, h, w)`` float32 patch-normalised thumbnails.
        chain_ptr: ``(chains + 1,)`` int64 first flat frame of each chain (cumulative frame counts).
        masks_by_flat_frame: bool ``(F, h, w)`` salient masks of the thumbnails, or None.
        good_by_flat_frame: bool ``(F,)`` quality-classifier verdicts; False frames are never kept.
        params: SESAME thresholds.
        sad_params: SAD shift ranges.

    Returns:
        Selector ``(nodes, k) -> per node (<= k,) int64`` rows of its frames; it may return none when
        no frame of the node is salient enough.
    """
    sal = np.asarray(saliency_scores_by_flat_frame, dtype=np.float64)
    thumbs = np.asarray(thumbs_by_flat_frame, dtype=np.float32)
    ptr = np.asarray(chain_ptr, dtype=np.int64)
    n = sal.shape[0]
    if sal.ndim != 1 or thumbs.ndim != 3 or thumbs.shape[0] != n or ptr.ndim != 1 or ptr[-1] != n:
        msg = f"need saliency (F,), thumbs (F, h, w), chain_ptr ending at F; got {sal.shape}, {thumbs.shape}"
        raise BadInputError(msg, field="saliency_scores_by_flat_frame")
    masks = None if masks_by_flat_frame is None else np.asarray(masks_by_flat_frame, dtype=bool)
    good = np.ones(n, dtype=bool) if good_by_flat_frame is None else np.asarray(good_by_flat_frame, bool)
    if good.shape != (n,) or (masks is not None and masks.shape != thumbs.shape):
        raise BadInputError(
            "good (F,) and masks (F, h, w) must match the frames", field="masks_by_flat_frame"
        )

    def select(nodes: Sequence[NodeFrames], k: int) -> list[I64]:
        orders = []
        for cands in nodes:
            flat = ptr[cands.chain] + cands.row
            order = np.lexsort((cands.row, cands.chain))
            orders.append(order[good[flat[order]]])
        flats = [(ptr[c.chain] + c.row)[o] for c, o in zip(nodes, orders, strict=True)]
        kept = build_salient_databases(
            flats,
            [c.xy_m[o] for c, o in zip(nodes, orders, strict=True)],
            sal,
            thumbs,
            masks,
            params,
            sad_params,
        )
        picks = []
        for order, f, keep in zip(orders, flats, kept, strict=True):
            best = keep[np.argsort(-sal[f][keep], kind="stable")][:k]
            picks.append(np.asarray(order[best], dtype=np.int64))
        return picks

    return select
