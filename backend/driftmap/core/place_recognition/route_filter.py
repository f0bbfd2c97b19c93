"""The route HMM of [SSLAM] (eq. 5-11): its parameters, the forward filter and the smoother.

The references of a dataset, in route order, are the nodes of a chain (node j = reference j); the query
images are taken in order, one filter step each. A step is the paper's: predict with a transition matrix
pi, weight by an observation O_i, normalise (:func:`driftmap.core.localisation.hmm.hmm_update`), report the best node
b(i) (eq. 11). What differs from the mine localiser (:class:`driftmap.core.localisation.localiser.Localiser`), and why:

* **Transitions.** pi moves the belief by 0..``reach_frames`` references per query frame, uniformly
  (eq. 9-10 with A_t = reach, distances in frames). With ``direction="forward"`` only forward moves are
  allowed: a dataset's query traversal follows the route in its order (the folder convention: sorted name
  order = route order). ``"both"`` is the paper's symmetric matrix, for vehicles that may reverse. The
  kernel's mean (1 reference per query frame for reach 2) is a speed prior: it holds at 1.5x but fails
  when the query runs at half or twice the references' speed (``docs/evaluation/place_recognition.md``).
  With ``speeds`` the speed relative to the references becomes part of the state instead: each speed
  state v moves the mass by v references (plus a +-1 jitter) and changes to a neighbouring speed with
  probability ``speed_change`` per step (:data:`ROUTE_ANY_SPEED`: 0-3x).
* **Observation.** Eq. 8 rescales d between the best and the worst *evaluated* node, so the best of a
  wrong neighbourhood always scores 1 and a lost belief never lets go (measured on Nordland: recall@1 0.004).
  Here each reference's own statistics decide: a sample of references, compared with the whole route
  (``calib_samples`` rows, neighbours excluded), gives reference j's typical unrelated distance m_j and
  its spread s_j (median, 1.4826 MAD), and ``O_i(j) = exp(gain * clip((m_j - d(i, j)) / s_j))``. A
  reference that resembles everything (a dark frame, a bland wall) has a low m_j and gains nothing
  from a low d: the "hub" references of [SESAME] section 3.4 stop attracting the belief.
* **Recovery.** ``uniform_mix`` of the prior is spread over the whole route each step (the global
  re-initialisation of the localiser, made continuous): a wrong lock decays once the true place keeps
  matching better.
* **Smoothing.** A batch of queries is known in full, so by default b(i) comes from the posterior given
  every frame, before and after i (forward-backward, :func:`smooth_route`), as SeqSLAM's sequences are
  centred on the query; ``smooth=False`` (:data:`ROUTE_ONLINE`) is the causal filter a vehicle runs live.
  The frames after a place are what tells a look-alike from it: on Nordland this, not the observation or
  the score, is what lifts AUC and recall at 100 % precision above SeqSLAM's.
* **Score.** The posterior within ``score_window_frames`` of b(i): the model's probability that the place
  lies within that tolerance (eq. 12's X_i(b(i)) for a window of nodes), mapped through the
  ``calibration`` knots. Combining it with the matched reference's distinctness (the localiser's
  ``score x distinct``) ranks right matches below wrong ones more often: measured, it lowers AUC.

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

from driftmap.core.localisation import hmm
from driftmap.core.types import F32, F64, I64
from driftmap.errors import BadInputError

__all__ = [
    "ROUTE_ANY_SPEED",
    "ROUTE_DEFAULT",
    "ROUTE_ONLINE",
    "RouteFilter",
    "RouteParams",
    "reference_stats",
    "route_transitions",
    "smooth_route",
    "window_mass",
]


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
    speeds: tuple[float, ...] = ()  # tracked speeds, refs per query frame (< 0: backwards); () = fixed kernel
    # (with speeds, reach_frames and direction are not used)
    speed_change: float = 0.01  # tracked: probability per step of moving to a neighbouring speed state
    # True: forward-backward over the whole query sequence (each b(i) also weighs the frames after i, as
    # SeqSLAM's centred sequences do); False: the causal filter (frames up to i), what a vehicle gets live
    smooth: bool = True
    # the reported score is the window posterior mapped through these (raw, P(right)) knots
    # (hmm.calibrated). Identity: the posterior is the probability. A logistic fitted on Nordland frames
    # 0-499 (bench/vpr_defaults.py prints it and its knots) calibrates those frames (ECE 0.076 -> 0.023)
    # but not others: frames 500-999 Brier 0.025 -> 0.031, corridor ECE 0.055 -> 0.118
    calibration: tuple[tuple[float, float], ...] = ((0.0, 0.0), (1.0, 1.0))

    def __post_init__(self) -> None:
        if self.reach_frames < 0 or self.score_window_frames < 0 or self.calib_exclude_frames < 0:
            raise BadInputError("reach, score window and exclusion must be >= 0", field="reach_frames")
        if self.direction not in ("forward", "both"):
            raise BadInputError(f"must be forward or both, got {self.direction!r}", field="direction")
        if not (self.gain > 0 and self.z_clip > 0 and 0.0 <= self.uniform_mix < 1.0):
            raise BadInputError("need gain > 0, z_clip > 0, uniform_mix in [0, 1)", field="gain")
        if self.calib_samples < 2:
            raise BadInputError(f"must be >= 2, got {self.calib_samples}", field="calib_samples")
        if list(self.speeds) != sorted(self.speeds) or not 0.0 <= self.speed_change <= 1.0:
            raise BadInputError("speeds must be ascending, speed_change in [0, 1]", field="speeds")
        knots = np.asarray(self.calibration, dtype=np.float64)
        if (
            knots.ndim != 2
            or knots.shape[0] < 2
            or knots.shape[1] != 2
            or knots[0, 0] != 0.0
            or knots[-1, 0] != 1.0
            or np.any(np.diff(knots[:, 0]) <= 0)
            or np.any(np.diff(knots[:, 1]) <= 0)
            or np.any((knots[:, 1] < 0) | (knots[:, 1] > 1))
        ):
            raise BadInputError(
                "must be (raw, probability) knots from raw 0 to 1, both strictly increasing (a flat"
                " stretch would tie right and wrong matches), probabilities in [0, 1]",
                field="calibration",
            )


#: Query and reference traversals at about the same speed (ratio 0-2, mean 1), like SeqSLAM's default
#: velocity range 0.8-1.2.
ROUTE_DEFAULT = RouteParams()
#: Any speed ratio from 0 (stopped) to 3: the speed is part of the state and changes slowly.
ROUTE_ANY_SPEED = RouteParams(speeds=(0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0))
#: The causal filter: each b(i) from the frames up to i only, as a vehicle localises live.
ROUTE_ONLINE = RouteParams(smooth=False)
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


def _shift(mass: F64, speed: float, adjoint: bool = False) -> F64:
    """``(N,)`` mass moved ``speed`` positions along the route (fractions split linearly); mass past the ends
    leaves. ``adjoint``: the transpose of that linear map (each position gathers from where its mass goes)."""
    out = np.zeros_like(mass)
    lo = math.floor(speed)
    frac = speed - lo
    n = mass.size
    for off, w in ((lo, 1.0 - frac), (lo + 1, frac)):
        if w <= 0 or abs(off) >= n:
            continue
        src, dst = (
            (slice(off, None), slice(None, n - off)) if off >= 0 else (slice(None, off), slice(-off, None))
        )
        if adjoint:
            out[dst] += w * mass[src]
        else:
            out[src] += w * mass[dst]
    return out


def _speed_mixing(k: int, change: float) -> F64:
    """``(K, K)`` exchange between neighbouring speed states: row k takes ``change / 2`` from each neighbour
    (the end states keep what would leave the speed range)."""
    mix = (1.0 - change) * np.eye(k)
    for i in range(k):
        mix[i, min(i + 1, k - 1)] += 0.5 * change
        mix[i, max(i - 1, 0)] += 0.5 * change
    return mix


def window_mass(place: F64, window: int) -> tuple[int, float]:
    """The peak of a ``(D,)`` belief and the belief within ``+-window`` references of it."""
    best = int(np.argmax(place))
    return best, float(place[max(0, best - window) : best + window + 1].sum())


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
        self.pi_t = self.pi.T.tocsr()
        k = max(1, len(params.speeds))
        self.mixing = _speed_mixing(k, params.speed_change)
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

    def transition(self, mass: F64, adjoint: bool = False) -> F64:
        """``(K, D)`` T(mass): one step's motion (eq. 9-10, or the tracked speeds) and the uniform mix.

        T is linear; ``adjoint`` applies its transpose, which carries the backward messages of
        :func:`smooth_route`.
        """
        p = self.params
        size = mass.size
        if not p.speeds:
            pi = self.pi_t if adjoint else self.pi
            moved = np.asarray(pi @ mass[0], dtype=np.float64)[None, :]
        elif adjoint:
            mixed = self.mixing.T @ mass
            moved = np.stack(  # the jitter kernel is symmetric: its own transpose
                [
                    _shift(np.convolve(b, SPEED_JITTER, mode="same"), v, True)
                    for b, v in zip(mixed, p.speeds, strict=True)
                ]
            )
        else:
            moved = self.mixing @ np.stack(
                [
                    np.convolve(_shift(b, v), SPEED_JITTER, mode="same")
                    for b, v in zip(mass, p.speeds, strict=True)
                ]
            )
        return np.asarray((1.0 - p.uniform_mix) * moved + p.uniform_mix * float(mass.sum()) / size)

    def step(self, d: F32 | F64) -> tuple[int, float]:
        """One filter step on a query's ``(D,)`` distance row; returns ``(b(i), raw score)``: the belief within
        ``score_window_frames`` of b(i), uncalibrated."""
        gamma = self.observation(d)
        if self.steps == 0:
            p = self.params
            prior = (1.0 - p.uniform_mix) * self.belief + p.uniform_mix / self.belief.size
        else:
            prior = self.transition(self.belief)
        k = prior.shape[0]
        post = hmm.hmm_update(prior.ravel(), self._all, np.tile(gamma, k), 1.0)
        self.belief = post.reshape(k, self.n)
        self.steps += 1
        return window_mass(self.place_belief, self.params.score_window_frames)


def smooth_route(d: F32 | F64, filt: RouteFilter) -> tuple[I64, F64]:
    """Forward-backward over a whole query sequence: b(i) and the raw score from every frame, before and after.

    The forward pass is :meth:`RouteFilter.step` (the filtered beliefs kept as float32; the uniform mix keeps
    them far above its underflow); the backward messages ``beta_i = T'(O_{i+1} beta_{i+1})`` (normalised)
    use the transpose of the same transition. The posterior of frame i is ``alpha_i beta_i``, normalised.

    Args:
        d: ``(Q, D)`` distance rows of the queries in traversal order.
        filt: a fresh filter (its statistics and parameters; it is stepped through every row).

    Returns:
        ``(b, raw)``: ``(Q,)`` int64 peak of each frame's posterior over the references and ``(Q,)`` float64
        the posterior within ``score_window_frames`` of it.
    """
    rows: NDArray[np.floating] = np.asarray(d)  # float32 stays float32 (memory)
    if rows.ndim != 2 or rows.shape[1] != filt.n:
        raise BadInputError(f"need a (Q, {filt.n}) matrix, got {rows.shape}", field="d")
    q = rows.shape[0]
    alphas = np.empty((q, *filt.belief.shape), dtype=np.float32)
    for i in range(q):
        filt.step(rows[i])
        alphas[i] = filt.belief
    best = np.zeros(q, dtype=np.int64)
    raw = np.zeros(q, dtype=np.float64)
    beta = np.full(filt.belief.shape, 1.0 / filt.belief.size)
    for i in range(q - 1, -1, -1):
        post = alphas[i] * beta
        best[i], raw[i] = window_mass(post.sum(axis=0) / post.sum(), filt.params.score_window_frames)
        if i > 0:
            beta = filt.transition(filt.observation(rows[i])[None, :] * beta, adjoint=True)
            beta /= beta.sum()
    return best, raw
