"""The few best distinct places in each row of a similarity matrix: its top-k local maxima.

:func:`~driftmap.core.loop_closure.descriptors.coarse_candidates` scores each query against every
earlier keyframe, a row of ``N`` similarities, and keeps the ``k`` best entries that are each the
maximum within ``nms_radius`` columns (non-maximum suppression along the reference axis: distinct
places, not neighbours of one peak). Suppressing over whole rows costs a few passes over a
``queries x N`` matrix, which on a whole mine is most of the loop-closure stage. :func:`top_local_maxima`
therefore looks only where the answer can be:

1. the row is cut into groups of ``GROUP`` columns; a group's raw maximum bounds every local maximum
   in it;
2. suppression and the top ``k`` run on the ``k + SPARE_GROUPS`` groups with the largest maxima
   (plus ``nms_radius`` columns either side, so that their entries see every neighbour);
3. the answer is exact when its ``k``-th value beats the best group left out; the rows where it
   does not (a peak spread over many groups, or fewer than ``k`` maxima) are done over the whole row.

Both paths give the values of suppression over the whole row, best first; which of exactly equal values
is taken, and in which order, may differ.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

__all__ = ["NEG", "hfilter_max", "top_k_rows", "top_local_maxima", "top_local_maxima_whole_rows"]

NEG = np.float32(-1e30)
""""Not eligible": below any cosine similarity, safe in OpenCV filters."""
GROUP = 64
"""Columns per group whose maxima bound the entries in it."""
SPARE_GROUPS = 4
"""Groups examined beyond ``k``: room for peaks that span two groups or lose to a neighbour."""


def hfilter_max(a: NDArray[np.float32], radius: int) -> NDArray[np.float32]:
    """Running maximum along axis 1 of ``(R, C)`` float32 over ``2 radius + 1`` columns (borders do not
    count); ``a`` itself when ``radius <= 0``."""
    if radius <= 0 or a.size == 0:
        return a
    kernel = np.ones((1, 2 * radius + 1), dtype=np.uint8)
    return np.asarray(cv2.dilate(a, kernel, borderType=cv2.BORDER_REPLICATE), dtype=np.float32)


def top_local_maxima(c: NDArray[np.float32], k: int, nms_radius: int) -> NDArray[np.int64]:
    """Columns of the ``k`` largest local maxima of each row of ``c``, best first; -1 pads.

    Args:
        c: ``(R, C)`` float32 similarities; entries equal to :data:`NEG` are never chosen. Not modified.
        k: maxima per row, >= 1.
        nms_radius: an entry counts when no entry within this many columns of its row is larger.

    Returns:
        ``(R, k)`` int64 column indices.
    """
    rows, cols = c.shape
    kk = min(k, cols)
    n_groups = -(-cols // GROUP)
    top = np.full((rows, kk), -1, dtype=np.int64)
    top_sim = np.full((rows, kk), NEG, dtype=np.float32)
    redo = np.ones(rows, dtype=bool)
    if rows and n_groups > kk + SPARE_GROUPS:
        top, top_sim, exact = _top_in_best_groups(c, kk, nms_radius, kk + SPARE_GROUPS)
        redo = ~exact
    if redo.any():
        top[redo], top_sim[redo] = _suppressed_top_k(c[redo], kk, nms_radius)
    return _padded(top, top_sim, k)


def top_local_maxima_whole_rows(c: NDArray[np.float32], k: int, nms_radius: int) -> NDArray[np.int64]:
    """:func:`top_local_maxima` by suppression over every column of every row (its fallback, and the
    baseline of ``bench/bench_loops.py --peaks``)."""
    return _padded(*_suppressed_top_k(c.copy(), min(k, c.shape[1]), nms_radius), k)


def _padded(top: NDArray[np.int64], top_sim: NDArray[np.float32], k: int) -> NDArray[np.int64]:
    """``(R, k)`` columns: ``top``'s where its value is eligible, -1 elsewhere and in the missing columns."""
    top = np.where(top_sim > NEG, top, -1)
    return np.pad(top, ((0, 0), (0, k - top.shape[1])), constant_values=-1)


def _suppressed_top_k(
    c: NDArray[np.float32], k: int, radius: int
) -> tuple[NDArray[np.int64], NDArray[np.float32]]:
    """Top ``k`` (``<= C``) columns and values per row after suppressing, in ``c`` itself, every entry with a
    larger one within ``radius`` columns."""
    np.copyto(c, NEG, where=c < hfilter_max(c, radius))
    return top_k_rows(c, k)


def _top_in_best_groups(
    c: NDArray[np.float32], k: int, radius: int, n_best: int
) -> tuple[NDArray[np.int64], NDArray[np.float32], NDArray[np.bool_]]:
    """Top ``k`` local maxima per row among the ``n_best`` groups with the largest raw maxima.

    Returns columns ``(R, k)``, values ``(R, k)`` best first, and ``(R,)`` whether each row's answer is
    exact: its ``k``-th value beats every group left out (or nothing eligible is left out).
    """
    rows, cols = c.shape
    g_max = _group_maxima(c)
    part = np.argpartition(-g_max, n_best, axis=1)
    best, left_out = part[:, :n_best], np.take_along_axis(g_max, part[:, n_best : n_best + 1], axis=1)[:, 0]
    offsets = np.arange(-radius, GROUP + radius)
    window = best[:, :, None] * GROUP + offsets[None, None, :]  # (R, n_best, GROUP + 2 radius) columns
    inside = window < cols
    vals = np.take_along_axis(c, np.clip(window, 0, cols - 1).reshape(rows, -1), axis=1)
    vals = vals.reshape(window.shape)  # clipped columns repeat the border entry: cv2's BORDER_REPLICATE
    centre = vals[:, :, radius : radius + GROUP]
    neighbours = centre.copy()
    for o in range(2 * radius + 1):
        np.maximum(neighbours, vals[:, :, o : o + GROUP], out=neighbours)
    kept = np.where((centre >= neighbours) & inside[:, :, radius : radius + GROUP], centre, NEG)
    kept = kept.reshape(rows, -1)
    columns = window[:, :, radius : radius + GROUP].reshape(rows, -1)
    idx, top = _sorted_top_k(kept, k)
    exact = (top[:, -1] > left_out) | (left_out <= NEG)
    return np.take_along_axis(columns, idx, axis=1), top, exact


def top_k_rows(c: NDArray[np.float32], k: int) -> tuple[NDArray[np.int64], NDArray[np.float32]]:
    """Column indices and values of the ``k`` largest entries of each row of ``(R, C)`` ``c``, largest
    first (``k <= C``).

    The ``k`` largest entries lie in the ``k`` column groups with the largest maxima, so a full
    partition runs only over a row's group maxima and then over ``k`` groups.
    """
    rows, cols = c.shape
    if cols > 4 * k * GROUP:
        best = np.argpartition(-_group_maxima(c), k - 1, axis=1)[:, :k]
        sub = (best[:, :, None] * GROUP + np.arange(GROUP)[None, None, :]).reshape(rows, -1)
        over = sub >= cols  # past the end of the shorter tail group
        sub = np.minimum(sub, cols - 1)
        vals = np.take_along_axis(c, sub, axis=1)
        vals[over] = NEG
    else:
        sub = np.broadcast_to(np.arange(cols), (rows, cols))
        vals = c
    idx, top = _sorted_top_k(vals, k)
    return np.take_along_axis(sub, idx, axis=1).astype(np.int64), top


def _group_maxima(c: NDArray[np.float32]) -> NDArray[np.float32]:
    """``(R, ceil(C / GROUP))`` maximum of each row's groups of ``GROUP`` columns (the last may be shorter)."""
    rows, cols = c.shape
    full = cols // GROUP
    g_max: NDArray[np.float32] = c[:, : full * GROUP].reshape(rows, full, GROUP).max(axis=2)
    if full * GROUP < cols:  # the ragged tail is one more group
        g_max = np.concatenate([g_max, c[:, full * GROUP :].max(axis=1, keepdims=True)], axis=1)
    return g_max


def _sorted_top_k(vals: NDArray[np.float32], k: int) -> tuple[NDArray[np.intp], NDArray[np.float32]]:
    """Positions and values of the ``k`` largest entries of each row of ``vals``, largest first."""
    part = np.argpartition(-vals, k - 1, axis=1)[:, :k] if k < vals.shape[1] else np.argsort(-vals, axis=1)
    top = np.take_along_axis(vals, part, axis=1)
    order = np.argsort(-top, axis=1, kind="stable")
    return np.take_along_axis(part, order, axis=1), np.take_along_axis(top, order, axis=1)
