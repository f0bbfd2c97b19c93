"""The HMM of paper 000 (eq. 5-11) over a route of reference images, for outside place-recognition data.

The references of a dataset, in route order, are the nodes of a chain (node j = reference j); the query
images are taken in order, one filter step each. A step is the paper's: predict with a transition matrix
pi, weight by an observation O_i, normalise (:func:`driftmap.core.hmm.hmm_update`), report the best node
b(i) (eq. 11). What differs from the mine localiser (:class:`driftmap.core.localiser.Localiser`), and why:

* **Transitions.** pi moves the belief by 0..``reach_frames`` references per query frame, uniformly
  (eq. 9-10 with A_t = reach, distances in frames). With ``direction="forward"`` only forward moves are
  allowed: a dataset's query traversal follows the route in its order (the folder convention: sorted name
  order = route order). ``"both"`` is the paper's symmetric matrix, for vehicles that may reverse. The
  kernel's mean (1 reference per query frame for reach 2) is a speed prior: measured, it fails when the
  query runs twice as fast (Nordland every 2nd query: AUC 0.07). With ``speeds`` the speed relative to the
  references becomes part of the state instead: each speed state v moves the mass by v references (plus
  a +-1 jitter) and changes to a neighbouring speed with probability ``speed_change`` per step
  (:data:`ROUTE_ANY_SPEED`: 0-3x, Nordland AUC 0.74 / 0.69 / 0.82 at 1x / 2x / 3x).
* **Observation.** Eq. 8 rescales d between the best and the worst *evaluated* node, so the best of a
  wrong neighbourhood always scores 1 and a lost belief never lets go (measured on Nordland: recall@1 0.004).
  Here each reference's own statistics decide: a sample of references, compared with the whole route
  (``calib_samples`` rows, neighbours excluded), gives reference j's typical unrelated distance m_j and
  its spread s_j (median, 1.4826 MAD), and ``O_i(j) = exp(gain * clip((m_j - d(i, j)) / s_j))``. A
  reference that resembles everything (a dark frame, a bland wall) has a low m_j and gains nothing
  from a low d: the "hub" references of paper 001 section 3.4 stop attracting the belief.
* **Recovery.** ``uniform_mix`` of the prior is spread over the whole route each step (the global
  re-initialisation of the localiser, made continuous): a wrong lock decays once the true place keeps
  matching better.
* **Score.** The belief within ``score_window_frames`` of b(i): how sure the filter is of the place to that
  tolerance (eq. 12's X_i(b(i)) for a window of nodes).

Every reference is compared with every query (a full row per step; references left out of the database
by SESAME have no observation), so there is no pruning to miss a recovery.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_array

from driftmap.core import hmm
from driftmap.core.vpr import (
    DEFAULT,
    Matches,
    PreparedImages,
    VprMethod,
    VprParams,
    check_pair,
    distance_matrix,
    match_single,
    prepare_images,
)
from driftmap.errors import BadInputError

__all__ = [
    "ROUTE_ANY_SPEED",
    "ROUTE_DEFAULT",
    "RouteFilter",
    "RouteParams",
    "calibration_sample",
    "match_route",
    "recognise_places",
    "reference_stats",
    "route_transitions",
]

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]
I64 = NDArray[np.int64]


@dataclass(frozen=True)
class RouteParams:
    """The route HMM (units: reference frames per query frame)."""

    reach_frames: int = 2  # moves of 0..reach references per query frame: mean 1 (same speed), up to 2x
    direction: Literal["forward", "both"] = "forward"  # forward only, or also backwards (paper's pi)
    gain: float = 0.5  # O = exp(gain * z): z = 2 (a clear match) weighs e = 2.7x a typical reference
    z_clip: float = 5.0  # |z| is clipped here so one frame cannot decide alone
    uniform_mix: float = 0.003  # fraction of the prior spread uniformly over the route each step
    score_window_frames: int = 2  # the score is the belief within +-this of the best node
    calib_samples: int = 64  # references compared with the route to learn each reference's statistics
    calib_exclude_frames: int = 5  # a sampled reference's neighbours within this show the same place
    block_rows: int = 64  # query rows computed at a time by the batch :func:`match_route`
    speeds: tuple[float, ...] = ()  # tracked speeds, refs per query frame (< 0: backwards); () = fixed kernel
    # (with speeds, reach_frames and direction are not used)
    speed_change: float = 0.01  # tracked: probability per step of moving to a neighbouring speed state

    def __post_init__(self) -> None:
        if self.reach_frames < 0 or self.score_window_frames < 0 or self.calib_exclude_frames < 0:
            raise BadInputError("reach, score window and exclusion must be >= 0", field="reach_frames")
        if self.direction not in ("forward", "both"):
            raise BadInputError(f"must be forward or both, got {self.direction!r}", field="direction")
        if not (self.gain > 0 and self.z_clip > 0 and 0.0 <= self.uniform_mix < 1.0):
            raise BadInputError("need gain > 0, z_clip > 0, uniform_mix in [0, 1)", field="gain")
        if self.calib_samples < 2 or self.block_rows < 1:
            raise BadInputError("need calib_samples >= 2 and block_rows >= 1", field="calib_samples")
        if list(self.speeds) != sorted(self.speeds) or not 0.0 <= self.speed_change <= 1.0:
            raise BadInputError("speeds must be ascending, speed_change in [0, 1]", field="speeds")


#: Query and reference traversals at about the same speed (ratio 0-2, mean 1), like SeqSLAM's default
#: velocity range 0.8-1.2.
ROUTE_DEFAULT = RouteParams()
#: Any speed ratio from 0 (stopped) to 3: the speed is part of the state and changes slowly.
ROUTE_ANY_SPEED = RouteParams(speeds=(0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0))
#: Each tracked speed moves the mass by v references, then spreads it by this kernel (jitter of +-1).
SPEED_JITTER = np.array([0.25, 0.5, 0.25])


def route_transitions(n: int, params: RouteParams = ROUTE_DEFAULT) -> csr_array:
    """(n, n) pi: ``pi[k, j]`` = probability of moving from reference j to k in one step.

    ``1 / (reach + 1)`` (forward) or ``1 / (2 reach + 1)`` (both) for every ``k - j`` in ``0..reach`` or
    ``-reach..reach``. Moves past either end of the route leave it, so the columns of the last (and, for
    ``both``, the first) ``reach`` references sum to less than 1: the ends do not trap the belief (the
    update renormalises).
    """
    if n < 1:
        raise BadInputError("the route needs at least one reference", field="n")
    lo = 0 if params.direction == "forward" else -params.reach_frames
    offsets = np.arange(lo, params.reach_frames + 1)
    j = np.repeat(np.arange(n, dtype=np.int64), offsets.size)
    k = j + np.tile(offsets, n)
    keep = (k >= 0) & (k < n)
    j, k = j[keep], k[keep]
    return csr_array((np.full(j.size, 1.0 / offsets.size), (k, j)), shape=(n, n))


def reference_stats(d_sample: F32, sample_index: I64, exclude_frames: int) -> tuple[F64, F64]:
    """Each reference's typical distance to unrelated images and its spread.

    Args:
        d_sample: ``(S, D)`` distances of ``S`` sampled references (as queries) to all ``D`` references.
        sample_index: ``(S,)`` int64 route index of each sampled reference.
        exclude_frames: entries with ``|j - sample| <= exclude_frames`` show the same place and are ignored.

    Returns:
        ``(m, s)``: ``(D,)`` float64 median and 1.4826 x median absolute deviation per reference over the
        finite, non-excluded samples; references without any get the medians over all references, and ``s``
        is floored at 1e-3 of its median so that no z-score divides by zero.
    """
    d = np.array(d_sample, dtype=np.float64)
    idx = np.asarray(sample_index, dtype=np.int64)
    if d.ndim != 2 or idx.shape != (d.shape[0],):
        raise BadInputError(f"need d (S, D) and index (S,), got {d.shape}, {idx.shape}", field="d_sample")
    cols = np.arange(d.shape[1])
    d[np.abs(cols[None, :] - idx[:, None]) <= exclude_frames] = np.nan
    d[~np.isfinite(d)] = np.nan
    has = np.isfinite(d).any(axis=0)
    if not has.any():
        return np.ones(d.shape[1]), np.ones(d.shape[1])
    m = np.full(d.shape[1], np.nan)
    s = np.full(d.shape[1], np.nan)
    m[has] = np.nanmedian(d[:, has], axis=0)
    s[has] = 1.4826 * np.nanmedian(np.abs(d[:, has] - m[has]), axis=0)
    m[~has] = np.median(m[has])
    s[~has] = np.median(s[has])
    floor = 1e-3 * max(float(np.median(s)), 1e-12)
    return m, np.maximum(s, floor)


def _shift(mass: F64, speed: float) -> F64:
    """``(N,)`` mass moved ``speed`` positions along the route (fractions split linearly); mass past the ends leaves."""
    out = np.zeros_like(mass)
    lo = math.floor(speed)
    frac = speed - lo
    n = mass.size
    for off, w in ((lo, 1.0 - frac), (lo + 1, frac)):
        if w <= 0 or abs(off) >= n:
            continue
        if off >= 0:
            out[off:] += w * mass[: n - off]
        else:
            out[:off] += w * mass[-off:]
    return out


class RouteFilter:
    """The route HMM, one query row at a time.

    The state is the belief over (speed state, reference): one speed state with the fixed transition
    matrix of :func:`route_transitions`, or ``len(params.speeds)`` tracked speeds.

    Args:
        ref_median: ``(D,)`` typical unrelated distance of each reference (:func:`reference_stats`).
        ref_scale: ``(D,)`` its spread, > 0.
        params: transitions, observation gain, mixing and score window.
    """

    def __init__(self, ref_median: F64, ref_scale: F64, params: RouteParams = ROUTE_DEFAULT) -> None:
        self.median = np.asarray(ref_median, dtype=np.float64)
        self.scale = np.asarray(ref_scale, dtype=np.float64)
        if self.median.ndim != 1 or self.scale.shape != self.median.shape or np.any(self.scale <= 0):
            raise BadInputError("need (D,) medians and positive (D,) scales", field="ref_scale")
        self.params = params
        self.n = self.median.size
        self.pi = route_transitions(self.n, params)
        k = max(1, len(params.speeds))
        self._all = np.arange(k * self.n, dtype=np.int64)
        self.belief = hmm.initial_belief(k * self.n).reshape(k, self.n)  # (K, D): speed state x reference
        self.steps = 0

    @property
    def place_belief(self) -> F64:
        """``(D,)`` belief over the references (summed over speed states)."""
        return np.asarray(self.belief.sum(axis=0), dtype=np.float64)

    def observation(self, d: F32 | F64) -> F64:
        """``(D,)`` float64 O_i: ``exp(gain * clip(z))``, 1 (no evidence) where d is not finite."""
        d = np.asarray(d, dtype=np.float64)
        if d.shape != (self.n,):
            raise BadInputError(f"need a ({self.n},) row, got {d.shape}", field="d")
        ok = np.isfinite(d)
        z = np.zeros(self.n)
        z[ok] = (self.median[ok] - d[ok]) / self.scale[ok]
        p = self.params
        return np.exp(p.gain * np.clip(z, -p.z_clip, p.z_clip))

    def predict(self) -> F64:
        """``(K, D)`` prior of the next step, before the uniform mix (eq. 9-10, or the tracked speeds)."""
        p = self.params
        if not p.speeds:
            return np.asarray(self.pi @ self.belief[0], dtype=np.float64)[None, :]
        moved = np.stack(
            [
                np.convolve(_shift(b, v), SPEED_JITTER, mode="same")
                for b, v in zip(self.belief, p.speeds, strict=True)
            ]
        )
        faster = np.vstack([moved[1:], moved[-1:]])  # the end states keep what would leave the speed range
        slower = np.vstack([moved[:1], moved[:-1]])
        return np.asarray((1.0 - p.speed_change) * moved + 0.5 * p.speed_change * (faster + slower))

    def step(self, d: F32 | F64) -> tuple[int, float]:
        """One filter step on a query's ``(D,)`` distance row; returns ``(b(i), score)``."""
        p = self.params
        gamma = self.observation(d)
        prior = self.belief if self.steps == 0 else self.predict()
        prior = (1.0 - p.uniform_mix) * prior + p.uniform_mix / prior.size
        k = prior.shape[0]
        post = hmm.hmm_update(prior.ravel(), self._all, np.tile(gamma, k), 1.0)
        self.belief = post.reshape(k, self.n)
        self.steps += 1
        place = self.place_belief
        best = int(np.argmax(place))
        w = p.score_window_frames
        return best, float(place[max(0, best - w) : best + w + 1].sum())


def calibration_sample(db: PreparedImages, count: int) -> I64:
    """``(S,)`` route indices of up to ``count`` usable references, evenly spread along the route."""
    usable = np.flatnonzero(db.usable)
    if usable.size == 0:
        return usable.astype(np.int64)
    pick = np.unique(np.linspace(0, usable.size - 1, min(count, usable.size)).round().astype(np.int64))
    return np.asarray(usable[pick], dtype=np.int64)


def match_route(
    query: PreparedImages,
    db: PreparedImages,
    params: VprParams = DEFAULT,
    route: RouteParams = ROUTE_DEFAULT,
    *,
    workers: int = 1,
) -> Matches:
    """Run the route HMM over all queries in order.

    Args:
        query: prepared query images in traversal order.
        db: prepared references in route order (same method and thumbnail size).
        params: the image comparison (SAD shifts; SESAME masks come with the prepared images).
        route: the filter.
        workers: threads computing distance rows.

    Returns:
        :class:`~driftmap.core.vpr.Matches`: b(i) and the windowed belief per query.
    """
    check_pair(query, db)
    sample = calibration_sample(db, route.calib_samples)
    pseudo = PreparedImages(
        db.thumbs[sample], None if db.masks is None else db.masks[sample], None, db.usable[sample]
    )
    m, s = reference_stats(
        distance_matrix(pseudo, db, params, workers=workers), sample, route.calib_exclude_frames
    )
    filt = RouteFilter(m, s, route)
    q = query.thumbs.shape[0]
    best = np.zeros(q, dtype=np.int64)
    score = np.zeros(q, dtype=np.float64)
    for b0 in range(0, q, route.block_rows):
        rows = slice(b0, min(q, b0 + route.block_rows))
        block = PreparedImages(
            query.thumbs[rows], None if query.masks is None else query.masks[rows], None, query.usable[rows]
        )
        for k, d in enumerate(distance_matrix(block, db, params, workers=workers)):
            best[b0 + k], score[b0 + k] = filt.step(d)
    return Matches(db_index=best, score=score)


def recognise_places(
    query_images: NDArray[np.uint8],
    db_images: NDArray[np.uint8],
    method: VprMethod = "sesame",
    *,
    temporal: bool = False,
    params: VprParams = DEFAULT,
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
        :class:`~driftmap.core.vpr.Matches`.
    """
    query = prepare_images(query_images, method, params)
    db = prepare_images(db_images, method, params)
    if temporal:
        return match_route(query, db, params, route, workers=workers)
    return match_single(distance_matrix(query, db, params, workers=workers))
