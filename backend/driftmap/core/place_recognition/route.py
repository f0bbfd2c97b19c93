"""Place recognition over a route of reference images with the HMM of [SSLAM] (eq. 5-11).

The references of a dataset, in route order, are the nodes of a chain; the queries are taken in order, one
filter step each. :mod:`driftmap.core.place_recognition.route_filter` holds the model (transitions,
observation, recovery, smoothing, score) and why it differs from the mine localiser; this module runs it
on prepared images: each reference's statistics (:func:`reference_model`), the filter over a distance
matrix (:func:`match_distances`), and the whole run on image stacks (:func:`recognise_places`).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from driftmap.core.localisation import hmm
from driftmap.core.place_recognition.route_filter import (
    ROUTE_DEFAULT,
    RouteFilter,
    RouteParams,
    reference_stats,
    smooth_route,
)
from driftmap.core.place_recognition.single import (
    VPR_DEFAULT,
    Matches,
    PreparedImages,
    VprMethod,
    VprParams,
    check_pair,
    distance_matrix,
    match_single,
    prepare_images,
)
from driftmap.core.types import F32, F64, I64

__all__ = [
    "calibrated",
    "calibration_sample",
    "match_distances",
    "match_route",
    "recognise_places",
    "reference_model",
]


def calibrated(raw: F64, knots: tuple[tuple[float, float], ...]) -> F64:
    """``(Q,)`` probabilities right of ``(Q,)`` raw scores: :func:`driftmap.core.localisation.hmm.calibrated` of each."""
    return np.array([hmm.calibrated(float(x), knots) for x in np.asarray(raw, dtype=np.float64)])


def calibration_sample(db: PreparedImages, count: int) -> I64:
    """``(S,)`` route indices of up to ``count`` usable references, evenly spread along the route."""
    usable = np.flatnonzero(db.usable)
    if usable.size == 0:
        return usable.astype(np.int64)
    pick = np.unique(np.linspace(0, usable.size - 1, min(count, usable.size)).round().astype(np.int64))
    return np.asarray(usable[pick], dtype=np.int64)


def reference_model(
    db: PreparedImages,
    params: VprParams = VPR_DEFAULT,
    route: RouteParams = ROUTE_DEFAULT,
    *,
    workers: int = 1,
) -> tuple[F64, F64]:
    """Each reference's typical unrelated distance and spread (:func:`reference_stats`), from
    ``route.calib_samples`` references of ``db`` compared with all of them."""
    sample = calibration_sample(db, route.calib_samples)
    pseudo = PreparedImages(
        db.thumbs[sample], None if db.masks is None else db.masks[sample], None, db.usable[sample]
    )
    return reference_stats(
        distance_matrix(pseudo, db, params, workers=workers), sample, route.calib_exclude_frames
    )


def match_distances(
    d: F32 | F64, ref_median: F64, ref_scale: F64, route: RouteParams = ROUTE_DEFAULT
) -> Matches:
    """The route HMM on a whole ``(Q, D)`` distance matrix (queries in traversal order), smoothed or causal.

    Returns:
        :class:`~driftmap.core.place_recognition.single.Matches`: b(i) and the calibrated window belief per query.
    """
    filt = RouteFilter(ref_median, ref_scale, route)
    if route.smooth:
        best, raw = smooth_route(d, filt)
    else:
        steps = [filt.step(row) for row in np.asarray(d)]
        best = np.array([b for b, _ in steps], dtype=np.int64)
        raw = np.array([r for _, r in steps], dtype=np.float64)
    return Matches(db_index=best, score=calibrated(raw, route.calibration))


def match_route(
    query: PreparedImages,
    db: PreparedImages,
    params: VprParams = VPR_DEFAULT,
    route: RouteParams = ROUTE_DEFAULT,
    *,
    workers: int = 1,
) -> Matches:
    """Run the route HMM over all queries in order.

    It keeps the ``(Q, D)`` distances and, smoothing, the ``(Q, K, D)`` forward beliefs (float32; K speed
    states): 8 MB for 1,000 x 1,000 images.

    Args:
        query: prepared query images in traversal order.
        db: prepared references in route order (same method and thumbnail size).
        params: the image comparison (SAD shifts; SESAME masks come with the prepared images).
        route: the HMM, smoothed or causal, and the score's calibration.
        workers: threads computing distance rows.

    Returns:
        :class:`~driftmap.core.place_recognition.single.Matches`: b(i) and the calibrated window posterior per query.
    """
    check_pair(query, db)
    m, s = reference_model(db, params, route, workers=workers)
    return match_distances(distance_matrix(query, db, params, workers=workers), m, s, route)


def recognise_places(
    query_images: NDArray[np.uint8],
    db_images: NDArray[np.uint8],
    method: VprMethod = "sesame",
    *,
    temporal: bool = False,
    params: VprParams = VPR_DEFAULT,
    route: RouteParams = ROUTE_DEFAULT,
    workers: int = 1,
) -> Matches:
    """The whole run on image stacks: prepare both, then single-image matching or the route HMM.

    Args:
        query_images: ``(Q, H, W)`` uint8 grey query images in traversal order.
        db_images: ``(D, H', W')`` uint8 grey references in route order (same aspect ratio as the queries).
        method: ``sad`` or ``sesame``.
        temporal: run the route HMM instead of single-image matching.
        params: thumbnails, SAD shifts, SESAME.
        route: the route HMM.
        workers: threads computing distance rows.

    Returns:
        :class:`~driftmap.core.place_recognition.single.Matches`.
    """
    query = prepare_images(query_images, method, params)
    db = prepare_images(db_images, method, params)
    if temporal:
        return match_route(query, db, params, route, workers=workers)
    return match_single(distance_matrix(query, db, params, workers=workers))
