"""Shifted sum-of-absolute-differences image comparison ([SSLAM] eq. 3/4, [SESAME] eq. 6).

The difference score of a query image ``a`` and a reference image ``b`` is the smallest, over
integer shifts ``(dx, dy)`` with ``|dx| <= x_max`` and ``|dy| <= y_max``, of the mean absolute
difference over the region where the two overlap::

    d(a, b) = min_{dx, dy}  sum_p w(p) |a(p) - b(p + (dx, dy))|  /  sum_p w(p)

with ``p = (x, y)`` running over the query pixels whose shifted partner lies inside ``b``. Without
a mask ``w = 1`` and the denominator is the overlap area ``(W - |dx|) (H - |dy|)``, so scores of
different shifts are comparable (eq. 3 divides by the resolution ``R_x R_y``; dividing by the
overlap instead keeps large shifts from looking better merely because fewer pixels count). With a
mask ``w`` in {0, 1} on the query this is SESAME's masked SAD ([SESAME] eq. 6): only salient
query pixels count, normalised by the number of salient pixels in the overlap. Paper 001 writes
the shift on the query, ``I_qr(y + dy, x + dx) - I_db(y, x)``; here it is on the reference, so its
``(dx, dy)`` is our ``(-dx, -dy)``.

Shift convention: at shift ``(dx, dy)`` query pixel ``(x, y)`` is compared with reference pixel
``(x + dx, y + dy)``, so when the reference shows the query's content moved right by 3 and down
by 1 pixel the minimum is at ``(3, 1)``.

Speed: the loop runs over the ``(2 x_max + 1)(2 y_max + 1)`` shifts and is vectorised over
references. A chunk of references is laid out as one tall ``(n H, W)`` image and compared with the
query tiled to the same height, so each shift costs one ``cv2.absdiff`` and one row-sum GEMV over
cache-sized memory; rows that straddle two references are simply dropped. :func:`sad_pairs` scores
arbitrary pairs the same way (both sides gathered into tall images), so many small comparisons cost
one pass over the shifts instead of one each.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.params import SAD_DEFAULT, SadParams

__all__ = [
    "SadResult",
    "sad_matrix",
    "sad_one_to_many",
    "sad_pairs",
]


@dataclass(frozen=True)
class SadResult:
    """Minimum-over-shifts SAD of one query against many references.

    Attributes:
        d: ``(M,)`` float32, mean absolute difference at the best shift (input intensity units);
            ``inf`` where no weighted pixel overlaps at any shift.
        shift_px: ``(M, 2)`` int16, the best ``(dx, dy)`` per reference, pixels.
    """

    d: NDArray[np.float32]
    shift_px: NDArray[np.int16]


def _shifts(max_dx: int, max_dy: int, height: int, width: int) -> list[tuple[int, int]]:
    if max_dx < 0 or max_dy < 0:
        raise ValueError(f"shift ranges must be >= 0, got {max_dx}, {max_dy}")
    if max_dx >= width or max_dy >= height:
        raise ValueError(f"shifts +-{max_dx}, +-{max_dy} leave no overlap in a {width}x{height} image")
    return [(dx, dy) for dy in range(-max_dy, max_dy + 1) for dx in range(-max_dx, max_dx + 1)]


def _overlap(dx: int, dy: int, height: int, width: int) -> tuple[slice, slice, slice, slice]:
    """Row/column slices of the query and of the reference that overlap at shift (dx, dy)."""
    qy = slice(max(0, -dy), height - max(0, dy))
    qx = slice(max(0, -dx), width - max(0, dx))
    return qy, qx, slice(qy.start + dy, qy.stop + dy), slice(qx.start + dx, qx.stop + dx)


def _check_mask(mask: NDArray | None, shape: tuple[int, ...]) -> NDArray[np.float32] | None:
    if mask is None:
        return None
    m = np.asarray(mask, dtype=np.float32)
    if m.shape != shape:
        raise ValueError(f"mask must have shape {shape}, got {m.shape}")
    if not np.all(np.isfinite(m)) or np.any(m < 0):
        raise ValueError("mask weights must be finite and >= 0")
    return m


def sad_one_to_many(
    query: NDArray,
    refs: NDArray,
    params: SadParams = SAD_DEFAULT,
    mask: NDArray | None = None,
) -> SadResult:
    """Shift-minimised, overlap-normalised SAD of one query against a stack of references.

    Args:
        query: ``(H, W)`` image, typically patch-normalised float32.
        refs: ``(M, H, W)`` references of the same size (float32 avoids a copy).
        params: the shift ranges ``max_shift_x_px``/``max_shift_y_px`` and the chunk memory bound.
        mask: optional ``(H, W)`` weights >= 0 on the query pixels (SESAME salient mask in {0, 1}).

    Returns:
        :class:`SadResult` with ``d`` ``(M,)`` and ``shift_px`` ``(M, 2)``.

    Raises:
        ValueError: shapes disagree, the shift range leaves no overlap, or the mask is invalid.
    """
    q = np.ascontiguousarray(query, dtype=np.float32)
    if q.ndim != 2:
        raise ValueError(f"query must be (H, W), got shape {q.shape}")
    r = np.ascontiguousarray(refs, dtype=np.float32)
    if r.ndim != 3 or r.shape[1:] != q.shape:
        raise ValueError(f"refs must be (M, {q.shape[0]}, {q.shape[1]}), got shape {r.shape}")
    height, width = q.shape
    shifts = _shifts(params.max_shift_x_px, params.max_shift_y_px, height, width)
    w = _check_mask(mask, q.shape)
    m_total = r.shape[0]
    chunk = max(1, min(m_total, params.chunk_bytes // (height * width * 4)))
    rows = np.empty(chunk * height, dtype=np.float32)
    diff_buf = np.empty(chunk * height * width, dtype=np.float32)  # reused: no allocation per shift
    ones = np.ones(width, dtype=np.float32)
    q_tall = np.tile(q, (chunk, 1))
    w_tall = None if w is None else np.tile(w, (chunk, 1))
    # The denominator depends only on the shift: overlap area, or weighted pixels in the overlap.
    overlaps = [_overlap(dx, dy, height, width) for dx, dy in shifts]
    denom = np.array(
        [
            (qy.stop - qy.start) * (qx.stop - qx.start) if w is None else float(w[qy, qx].sum())
            for qy, qx, _, _ in overlaps
        ],
        dtype=np.float64,
    )
    scores = np.full((len(shifts), m_total), np.inf, dtype=np.float32)  # per shift, per reference
    for c0 in range(0, m_total, chunk):
        n = min(chunk, m_total - c0)
        r_tall = r[c0 : c0 + n].reshape(n * height, width)
        for k, ((_dx, dy), (qy, qx, _, rx)) in enumerate(zip(shifts, overlaps, strict=True)):
            if denom[k] <= 0:
                continue
            # Tall-image rows k0..k1 of the query pair with rows k0+dy..k1+dy of the references.
            k0, k1 = max(0, -dy), n * height - max(0, dy)
            cols = qx.stop - qx.start
            diff = diff_buf[: (k1 - k0) * cols].reshape(k1 - k0, cols)
            cv2.absdiff(q_tall[k0:k1, qx], r_tall[k0 + dy : k1 + dy, rx], dst=diff)
            if w_tall is not None:
                np.multiply(diff, w_tall[k0:k1, qx], out=diff)
            np.matmul(diff, ones[:cols], out=rows[k0:k1])
            np.sum(rows[: n * height].reshape(n, height)[:, qy], axis=1, out=scores[k, c0 : c0 + n])
    scores *= (1.0 / np.where(denom > 0, denom, 1.0)).astype(np.float32)[:, None]
    best_idx = np.argmin(scores, axis=0)  # the first shift of the lowest score, as a running minimum keeps
    best = scores[best_idx, np.arange(m_total)]
    shift_arr = np.asarray(shifts, dtype=np.int16).reshape(-1, 2)
    return SadResult(d=best, shift_px=shift_arr[best_idx])


def sad_matrix(
    queries: NDArray,
    refs: NDArray,
    params: SadParams = SAD_DEFAULT,
    masks: NDArray | None = None,
) -> NDArray[np.float32]:
    """Confusion matrix of shift-minimised SAD scores, computed in memory-bounded blocks.

    Row by row with :func:`sad_one_to_many`, whose reference chunks of about ``params.chunk_bytes``
    stay in cache through all shifts; peak extra memory is about three chunks plus the output.

    Args:
        queries: ``(Q, H, W)`` images.
        refs: ``(M, H, W)`` images of the same size.
        params: shift ranges and chunk memory bound.
        masks: optional query weights, ``(H, W)`` shared by all queries or ``(Q, H, W)``.

    Returns:
        ``(Q, M)`` float32: ``out[i, j]`` = d(query i, reference j), as :func:`sad_one_to_many`.

    Raises:
        ValueError: shapes disagree or a mask is invalid.
    """
    qs = np.asarray(queries, dtype=np.float32)
    r = np.ascontiguousarray(refs, dtype=np.float32)
    if qs.ndim != 3 or r.ndim != 3 or qs.shape[1:] != r.shape[1:]:
        raise ValueError(f"queries (Q, H, W) and refs (M, H, W) must share H, W; got {qs.shape}, {r.shape}")
    if masks is not None:
        masks = np.asarray(masks, dtype=np.float32)
        if masks.shape == qs.shape[1:]:
            masks = np.broadcast_to(masks, qs.shape)
        if masks.shape != qs.shape:
            raise ValueError(f"masks must be (H, W) or (Q, H, W) = {qs.shape}, got {masks.shape}")
    out = np.empty((qs.shape[0], r.shape[0]), dtype=np.float32)
    for i in range(qs.shape[0]):  # each row streams the references once, chunk by cache-sized chunk
        out[i] = sad_one_to_many(qs[i], r, params, None if masks is None else masks[i]).d
    return out


# --- Registration of two images of one scene: coarse-to-fine, two-sided, masked SAD -------------


def sad_pairs(
    frames: NDArray,
    qi: NDArray,
    rj: NDArray,
    params: SadParams = SAD_DEFAULT,
    masks: NDArray | None = None,
) -> SadResult:
    """Shift-minimised SAD of ``frames[qi[p]]`` against ``frames[rj[p]]`` for arbitrary pairs ``p``.

    The conventions are those of :func:`sad_one_to_many` ([SSLAM] eq. 3; with ``masks``, [SESAME] eq. 6
    with the query's mask). Pairs are gathered in chunks of about ``params.chunk_bytes`` and laid out as
    two tall images, so each shift costs one ``cv2.absdiff`` and one sum per pair whatever the pairs are.
    A pair's result does not depend on the other pairs of its call (so a search split over processes
    scores alike).

    Args:
        frames: ``(N, H, W)`` float32 patch-normalised frames.
        qi: ``(P,)`` int query frame indices.
        rj: ``(P,)`` int reference frame indices.
        params: shift ranges ``+-max_shift_x_px``, ``+-max_shift_y_px`` and the chunk memory bound.
        masks: optional ``(N, H, W)`` weights in {0, 1} (bool or float) of each frame's pixels; the
            query's weights ``masks[qi[p]]`` count, normalised by their sum over the overlap.

    Returns:
        :class:`SadResult` with ``d`` ``(P,)`` (``inf`` where no weighted pixel overlaps at any shift) and
        ``shift_px`` ``(P, 2)``: query pixel ``(x, y)`` matches reference pixel ``(x + dx, y + dy)``.

    Raises:
        ValueError: bad shapes or indices, or a shift range leaving no overlap.
    """
    f = np.ascontiguousarray(frames, dtype=np.float32)
    qi = np.asarray(qi, dtype=np.int64)
    rj = np.asarray(rj, dtype=np.int64)
    if f.ndim != 3 or qi.ndim != 1 or qi.shape != rj.shape:
        raise ValueError(
            f"frames (N, H, W), qi (P,), rj (P,) expected, got {f.shape}, {qi.shape}, {rj.shape}"
        )
    if masks is not None and np.shape(masks) != f.shape:
        raise ValueError(f"masks must have the frames' shape {f.shape}, got {np.shape(masks)}")
    n, height, width = f.shape
    if qi.size and (min(qi.min(), rj.min()) < 0 or max(qi.max(), rj.max()) >= n):
        raise ValueError(f"pair indices must lie in 0 .. {n - 1}")
    shifts = _shifts(params.max_shift_x_px, params.max_shift_y_px, height, width)
    overlaps = [_overlap(dx, dy, height, width) for dx, dy in shifts]
    indicators = _overlap_indicators(overlaps, height, width)
    best = np.full(qi.size, np.inf, dtype=np.float32)
    best_k = np.zeros(qi.size, dtype=np.int64)
    chunk = max(1, params.chunk_bytes // (height * width * 4))
    diff_buf = np.empty(chunk * height * width, dtype=np.float32)  # reused: no allocation per shift
    for c0 in range(0, qi.size, chunk):
        c1 = min(qi.size, c0 + chunk)
        m = c1 - c0
        a = f[qi[c0:c1]].reshape(m * height, width)
        b = f[rj[c0:c1]].reshape(m * height, width)
        w = None if masks is None else np.asarray(masks[qi[c0:c1]], dtype=np.float32)
        weight = None
        if w is not None:  # (m, S) weight in each shift's overlap: exact float32 sums of 0/1 weights
            rows, cols, iy, ix = indicators
            weight = (rows @ (w.reshape(m * height, width) @ cols).reshape(m, height, -1))[:, iy, ix]
        for k, ((_, dy), (qy, qx, _, rx)) in enumerate(zip(shifts, overlaps, strict=True)):
            k0, k1 = max(0, -dy), m * height - max(0, dy)  # rows straddling two pairs are dropped below
            cols = qx.stop - qx.start
            diff = diff_buf[: m * height * cols].reshape(m * height, cols)
            cv2.absdiff(a[k0:k1, qx], b[k0 + dy : k1 + dy, rx], dst=diff[k0:k1])
            if w is not None:
                np.multiply(diff[k0:k1], w.reshape(m * height, width)[k0:k1, qx], out=diff[k0:k1])
            # Each pair's overlap is one contiguous run of the buffer, summed on its own (numpy's pairwise
            # sum): a pair's d is the same whatever else its batch holds (a BLAS row sum is not).
            overlap = diff.reshape(m, height, cols)[:, qy, :].reshape(m, -1)
            score = np.add.reduce(overlap, axis=1)
            if weight is None:
                score *= np.float32(1.0 / ((qy.stop - qy.start) * cols))
            else:
                score = np.where(weight[:, k] > 0, score / np.maximum(weight[:, k], 1.0), np.float32(np.inf))
            better = score < best[c0:c1]
            best[c0:c1][better] = score[better]
            best_k[c0:c1][better] = k
    shift_arr = np.asarray(shifts, dtype=np.int16).reshape(-1, 2)
    return SadResult(d=best, shift_px=shift_arr[best_k])


def _overlap_indicators(
    overlaps: list[tuple[slice, slice, slice, slice]], height: int, width: int
) -> tuple[NDArray[np.float32], NDArray[np.float32], list[int], list[int]]:
    """0/1 indicators of the overlaps' distinct row and column ranges, and each shift's pair of them.

    Returns ``rows`` ``(R, H)``, ``cols`` ``(W, C)`` float32 and, per shift, its row range ``iy`` and
    column range ``ix``: the weight of shift k in an ``(H, W)`` image ``w`` is
    ``(rows @ w @ cols)[iy[k], ix[k]]``.
    """
    row_ranges = sorted({(qy.start, qy.stop) for qy, _, _, _ in overlaps})
    col_ranges = sorted({(qx.start, qx.stop) for _, qx, _, _ in overlaps})
    rows = np.zeros((len(row_ranges), height), dtype=np.float32)
    for i, (y0, y1) in enumerate(row_ranges):
        rows[i, y0:y1] = 1.0
    cols = np.zeros((width, len(col_ranges)), dtype=np.float32)
    for j, (x0, x1) in enumerate(col_ranges):
        cols[x0:x1, j] = 1.0
    iy = [row_ranges.index((qy.start, qy.stop)) for qy, _, _, _ in overlaps]
    ix = [col_ranges.index((qx.start, qx.stop)) for _, qx, _, _ in overlaps]
    return rows, cols, iy, ix
