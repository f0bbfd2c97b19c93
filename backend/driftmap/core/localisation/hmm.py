"""HMM place recognition on the stored map ([SSLAM] III-B, eq. 4-10): node scores, transitions, update.

One filter step, as :class:`driftmap.core.localisation.localiser.Localiser` runs it:

1. predict: ``prior = pi X_{i-1}`` with the transition matrix pi of eq. 9-10 for A_t = max speed x the
   timestamp gap of this frame (a dropped frame widens the reach; a reach beyond the stored shortest
   paths makes the prior uniform). :class:`~driftmap.core.localisation.transitions.TransitionModel` caches one matrix per
   quantised A_t.
   Every column keeps mass on its own node (A(x, x) = 0 < A_t), so a vehicle that stops stays put,
   and A is symmetric, so nothing assumes forward travel: reversing is as likely as driving on.
2. choose the states to evaluate (eq. 8, X^t_{i-1}): the ``n_t`` nodes of largest prior, plus every node
   tied with the maximum so that a flat (global) belief evaluates the whole map (:func:`select_states`).
3. compare the query with those nodes only (eq. 4, :func:`compare_nodes`): d(i, j) = min over node j's
   frames of the shifted, overlap-normalised SAD of :func:`driftmap.core.imaging.sad.sad_one_to_many`.
4. update (eq. 5-8, :func:`hmm_update`): ``X_i = O_i * prior`` elementwise, normalised to sum 1, with
   ``O_i(j) = gamma(d(i, j))`` for evaluated nodes and epsilon for the rest.

Eq. 8 as printed reads "gamma = (d_max - k)/(d_max - d_min) if that is < p_t"; the text after it says values
*below* p_t become epsilon, which is what :func:`observation` implements.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.params import SAD_DEFAULT, SadParams
from driftmap.core.imaging.sad import sad_one_to_many
from driftmap.core.types import F32, F64, I64
from driftmap.errors import BadInputError

__all__ = [
    "DEFAULT",
    "PAPER",
    "HmmParams",
    "calibrated",
    "check_node_ptr",
    "compare_nodes",
    "compare_references",
    "hmm_update",
    "initial_belief",
    "observation",
    "select_states",
]

_FLAT_TOLERANCE = 1e-9  # relative spread below which a belief counts as flat (global)


_NON_NEGATIVE = (
    "n_probe",
    "lost_frames",
    "lost_confidence",
    "x_thresh",
    "still_ratio",
    "confirm_frames",
    "relocate_ratio",
)


@dataclass(frozen=True)
class HmmParams:
    """Parameters of the HMM temporal filter ([SSLAM] eq. 5-12) and of lost detection (driftmap's own)."""

    max_speed_mps: float = 7.0  # fastest vehicle travel; A_t = max_speed_mps x frame gap (eq. 10)
    min_a_t_m: float = 7.5  # floor on A_t: keep it above the node spacing N or the belief can never move
    a_t_quantum_m: float = (
        1.0  # A_t is rounded up to a multiple of this; one transition matrix is cached each
    )
    p_t: float = 0.5  # eq. 8: a normalised score (d_max - d)/(d_max - d_min) below this becomes epsilon
    epsilon: float = 0.01  # eq. 8: observation of a poor match and of every node not evaluated
    n_t: int = 40  # eq. 8: the nodes of largest prior pi X_{i-1} that are compared with the query
    x_thresh: float = 0.5  # eq. 12: a place match needs X_i(b(i)) >= x_thresh
    n_probe: int = 8  # extra nodes compared per frame (rotating through the map) to gauge an unrelated d
    lost_confidence: float = 0.02  # a frame with X_i(b(i)) below this counts as lost
    lost_distinct_ratio: float = 0.95  # lost when d(b(i)) / median d of the compared nodes is above this
    lost_elsewhere_ratio: float = 1.0  # lost when d(b(i)) / least d of compared far nodes is above this
    lost_frames: int = 20  # this many lost frames in a row (2 s at 10 fps) re-initialise globally; 0: never
    # a frame is reported lost (Estimate.lost, never matched) once this many lost frames in a row are counted:
    # a right track fails the test on single frames (look-alikes beat one view in about 1 frame in 6), and
    # a lost flag on each of them would make the control room's "lost" status flicker; 1: every lost frame
    lost_report_frames: int = 3
    # a frame whose view changed less than still_ratio x its least d to the map since the last frame is "still"
    # (the vehicle stands): it repeats the evidence of the last frame, so once the belief has followed
    # confirm_frames moving frames since its last global start, still lost frames do not count towards
    # re-initialising it (a vehicle stopped where the map's views match poorly is not elsewhere); 0: off
    still_ratio: float = 0.5
    confirm_frames: int = 10
    # weight of the newest frame in the track's running distinctness (Estimate.distinct); 1: this frame only
    distinct_memory: float = 0.2
    # relocation: a compared node more than two frame reaches from b(i) whose d is this many times below
    # d(b(i)) (d(b) / d(far) >= relocate_ratio) gets relocate_share of the belief, a second hypothesis that
    # the next frames confirm or drop: a belief stuck on a look-alike, whose lost frames keep being
    # interrupted by a passing one, still finds the place when it is probed (no right frame of the simulated
    # sites went above 1.16); 0: off
    relocate_ratio: float = 1.25
    relocate_share: float = 0.5
    # odometry: with a usable step the belief moves by the distance driven, one minimum-reach transition
    # per this many metres (a share of one per frame) instead of max speed x frame gap (eq. 9-10): a stopped
    # vehicle's belief does not spread, a moving one's spreads with the distance it drove
    odometry_hop_m: float = 3.5
    # the reported confidence is the calibration of score x distinct: piecewise linear through these
    # (raw, probability right) knots, raw ascending from 0 to 1. Fitted (driftmap.core.place_recognition.metrics.fit_calibration:
    # Platt scaling, 5 % of the raw score kept) on the simulated seed-7 small and medium sites' localisation
    # drives, every condition, global start, odometry, 15 m tolerance (`driftmap report localisation SITE
    # --truth` prints the fit); raw 0 (views that tell nothing apart) is pinned to 0; seed 11 is the
    # held-out check (docs/evaluation/localisation.md)
    calibration: tuple[tuple[float, float], ...] = (
        (0.0, 0.0), (0.05, 0.9513), (0.1, 0.9546), (0.15, 0.9573), (0.2, 0.9599), (0.25, 0.9624),
        (0.3, 0.965), (0.35, 0.9675), (0.4, 0.97), (0.45, 0.9725), (0.5, 0.975), (0.55, 0.9775),
        (0.6, 0.98), (0.65, 0.9825), (0.7, 0.985), (0.75, 0.9875), (0.8, 0.99), (0.85, 0.9925),
        (0.9, 0.995), (0.95, 0.9975), (1.0, 1.0),
    )  # fmt: skip
    # matched: the calibrated confidence is at least this (and not lost); the lowest round value at which no
    # frame of the seed-7 sites' drives was matched wrong (their wrong frames reached 0.94)
    confidence_threshold: float = 0.95

    def __post_init__(self) -> None:
        for name in ("max_speed_mps", "min_a_t_m", "a_t_quantum_m", "epsilon", "lost_distinct_ratio"):
            if not getattr(self, name) > 0:
                raise BadInputError(f"must be positive, got {getattr(self, name)}", field=name)
        if not 0.0 <= self.p_t <= 1.0:
            raise BadInputError(f"must be in [0, 1], got {self.p_t}", field="p_t")
        if self.epsilon >= 1.0:
            raise BadInputError(f"must be below 1, got {self.epsilon}", field="epsilon")
        if self.n_t < 1:
            raise BadInputError(f"must be >= 1, got {self.n_t}", field="n_t")
        if self.lost_report_frames < 1:
            raise BadInputError(f"must be >= 1, got {self.lost_report_frames}", field="lost_report_frames")
        if not 0.0 < self.relocate_share < 1.0:
            raise BadInputError(f"must be in (0, 1), got {self.relocate_share}", field="relocate_share")
        if not 0.0 < self.distinct_memory <= 1.0:
            raise BadInputError(f"must be in (0, 1], got {self.distinct_memory}", field="distinct_memory")
        if not self.odometry_hop_m > 0:
            raise BadInputError(f"must be positive, got {self.odometry_hop_m}", field="odometry_hop_m")
        if not 0.0 <= self.confidence_threshold <= 1.0:
            raise BadInputError(
                f"must be in [0, 1], got {self.confidence_threshold}", field="confidence_threshold"
            )
        knots = np.asarray(self.calibration, dtype=np.float64)
        if (
            knots.ndim != 2
            or knots.shape[1] != 2
            or knots.shape[0] < 2
            or np.any(np.diff(knots[:, 0]) <= 0)
            or np.any(np.diff(knots[:, 1]) < 0)
            or knots[0, 0] != 0.0
            or knots[-1, 0] != 1.0
            or np.any((knots[:, 1] < 0) | (knots[:, 1] > 1))
        ):
            raise BadInputError(
                "must be (raw, probability) knots from raw 0 to 1, both non-decreasing, in [0, 1]",
                field="calibration",
            )
        for name in _NON_NEGATIVE:
            if getattr(self, name) < 0:
                raise BadInputError(f"must be >= 0, got {getattr(self, name)}", field=name)


#: As close to the paper as it says: no probes and no lost detection (it assumes a known start).
PAPER = HmmParams(n_probe=0, lost_frames=0, lost_confidence=0.0, relocate_ratio=0.0)
#: driftmap's filter: the paper plus probes, relocation and global re-initialisation when lost.
DEFAULT = HmmParams()


def calibrated(raw: float, knots: tuple[tuple[float, float], ...]) -> float:
    """The probability that a frame of raw confidence ``raw`` (in [0, 1]) is right: piecewise linear
    through ``knots`` (:attr:`HmmParams.calibration`)."""
    k = np.asarray(knots, dtype=np.float64)
    return float(np.interp(min(max(raw, 0.0), 1.0), k[:, 0], k[:, 1]))


def check_node_ptr(node_ptr: I64, n_frames: int) -> None:
    """Raise :class:`BadInputError` unless (M + 1,) ``node_ptr`` runs non-decreasing from 0 to ``n_frames``."""
    if node_ptr.ndim != 1 or node_ptr.size < 1 or node_ptr[0] != 0 or node_ptr[-1] != n_frames:
        raise BadInputError(f"node_ptr must run from 0 to {n_frames}", field="node_ptr")
    if np.any(np.diff(node_ptr) < 0):
        raise BadInputError("node_ptr must be non-decreasing", field="node_ptr")


def compare_nodes(
    query: F32,
    thumbs: F32,
    node_ptr: I64,
    nodes: I64,
    sad_params: SadParams = SAD_DEFAULT,
    mask: NDArray[np.bool_] | None = None,
) -> F32:
    """Node difference scores of eq. 4 for the requested nodes only (:func:`compare_references` without
    which reference frame gave each)."""
    return compare_references(query, thumbs, node_ptr, nodes, sad_params, mask)[0]


def compare_references(
    query: F32,
    thumbs: F32,
    node_ptr: I64,
    nodes: I64,
    sad_params: SadParams = SAD_DEFAULT,
    mask: NDArray[np.bool_] | None = None,
) -> tuple[F32, I64]:
    """Node difference scores of eq. 4 for the requested nodes only, and the reference frame that gave each.

    Args:
        query: (H, W) float32 pre-processed (patch-normalised) query thumbnail.
        thumbs: (S, H, W) float32 reference thumbnails of every node, node j's in rows
            ``node_ptr[j]:node_ptr[j + 1]``.
        node_ptr: (M + 1,) int64 offsets of each node's frames in ``thumbs``.
        nodes: (n,) int64 node indices to compare; only their frames are touched.
        sad_params: shift ranges of the SAD.
        mask: optional (H, W) bool SESAME salient mask of the query ([SESAME] eq. 6): only salient query
            pixels count, normalised by their number in the overlap; None compares every pixel.

    Returns:
        (n,) float32 d(i, j): the minimum over node j's frames of the shifted SAD (intensity units of the
        thumbnails); ``inf`` for a node that holds no frame. (n,) int64 the row of ``thumbs`` of the frame
        that gave that minimum; -1 for a node that holds no frame.
    """
    nodes = np.asarray(nodes, dtype=np.int64)
    if thumbs.ndim != 3 or query.shape != thumbs.shape[1:]:
        raise BadInputError(f"query {query.shape} and thumbs {thumbs.shape} disagree", field="query")
    m = node_ptr.size - 1
    if nodes.ndim != 1 or (nodes.size and (nodes.min() < 0 or nodes.max() >= m)):
        raise BadInputError(f"nodes must be (n,) indices below {m}", field="nodes")
    start, count = node_ptr[nodes], node_ptr[nodes + 1] - node_ptr[nodes]
    out = np.full(nodes.size, np.inf, dtype=np.float32)
    best_ref = np.full(nodes.size, -1, dtype=np.int64)
    has = count > 0
    if not has.any():
        return out, best_ref
    start, count = start[has], count[has]
    total = int(count.sum())
    seg = np.cumsum(count) - count
    flat = np.repeat(start - seg, count) + np.arange(total, dtype=np.int64)
    if total == thumbs.shape[0] and np.array_equal(start, node_ptr[:-1][node_ptr[1:] > node_ptr[:-1]]):
        refs = thumbs  # every node in map order: no gather copy
    else:
        refs = thumbs[flat]
    if mask is None:
        d = sad_one_to_many(query, refs, sad_params).d
    else:
        d = sad_one_to_many(query, refs, sad_params, mask=mask).d
    out[has] = np.minimum.reduceat(d, seg)
    # each node's least d first within its segment: the frame that gave the node's score
    order = np.lexsort((d, np.repeat(np.arange(count.size), count)))
    best_ref[has] = flat[order[seg]]
    return out, best_ref


def observation(d: F32 | F64, p_t: float, epsilon: float) -> F64:
    """Observation values gamma of eq. 8 for the scores evaluated this step.

    Args:
        d: (n,) difference scores of the evaluated nodes; non-finite ones (no frame) are poor matches.
        p_t: normalised scores below this become ``epsilon``.
        epsilon: the value of a poor match.

    Returns:
        (n,) float64 ``(d_max - d) / (d_max - d_min)`` (1 at the best node) where that is >= p_t, else
        epsilon; d_max, d_min are over the finite scores given. When they are equal every finite score gets 1
        (the frame tells nothing apart).
    """
    d = np.asarray(d, dtype=np.float64)
    out = np.full(d.shape, epsilon, dtype=np.float64)
    ok = np.isfinite(d)
    if not ok.any():
        return out
    d_max, d_min = float(d[ok].max()), float(d[ok].min())
    if d_max <= d_min:
        out[ok] = 1.0
        return out
    gamma = (d_max - d[ok]) / (d_max - d_min)
    out[ok] = np.where(gamma >= p_t, gamma, epsilon)
    return out


def is_global(belief: F64) -> bool:
    """True when (M,) ``belief`` is flat: no node more likely than another (a global start or re-start).

    The transition of eq. 9 must leave such a belief as it is: its columns are normalised, not its rows, so
    pi X of a flat X favours nodes with many neighbours within A_t (by up to 2.1x on medium seed 11), and
    :func:`select_states` would then compare only the N_t best-linked nodes instead of the whole map.
    """
    top = float(belief.max())
    return top - float(belief.min()) <= top * _FLAT_TOLERANCE


def select_states(prior: F64, n_t: int) -> I64:
    """The states to evaluate (eq. 8): the ``n_t`` largest priors and every node tied with the maximum.

    Args:
        prior: (M,) float64 predicted belief ``pi X_{i-1}``.
        n_t: number of top states.

    Returns:
        (n,) int64 sorted node indices; all M nodes when the belief is flat (global search).
    """
    m = prior.size
    if n_t >= m:
        return np.arange(m, dtype=np.int64)
    top = np.argpartition(prior, m - n_t)[m - n_t :]
    flat_top = np.flatnonzero(prior >= prior.max() * (1.0 - _FLAT_TOLERANCE))
    return np.union1d(top, flat_top).astype(np.int64)


def hmm_update(prior: F64, nodes: I64, gamma: F64, epsilon: float) -> F64:
    """Eq. 5-7 and the normalisation of eq. 6: ``X_i = O_i * prior`` with epsilon where not evaluated.

    Args:
        prior: (M,) float64 predicted belief ``pi X_{i-1}``.
        nodes: (n,) int64 evaluated nodes.
        gamma: (n,) float64 their observation values (:func:`observation`).
        epsilon: observation of the nodes not evaluated.

    Returns:
        (M,) float64 posterior X_i summing to 1 (uniform if the product vanishes everywhere).
    """
    post = prior * epsilon
    post[nodes] = prior[nodes] * gamma
    total = float(post.sum())
    if not total > 0 or not math.isfinite(total):
        return np.full(prior.size, 1.0 / prior.size)
    return np.asarray(post / total, dtype=np.float64)


def add_hypothesis(belief: F64, node: int, share: float) -> F64:
    """(M,) ``(1 - share) x belief`` with ``share`` added at ``node``: a second place for the next frames to
    confirm or drop (the sum stays 1)."""
    out = (1.0 - share) * np.asarray(belief, dtype=np.float64)
    out[node] += share
    return out


def initial_belief(
    n_nodes: int, start_node: int | None = None, centres_m: F64 | None = None, radius_m: float = 0.0
) -> F64:
    """X_0: uniform over the map (global) when the start is unknown, else peaked at the start.

    Args:
        n_nodes: number of nodes M.
        start_node: the known start node, or None.
        centres_m: (M, 2) float64 node centres, metres; needed when ``radius_m > 0``.
        radius_m: spread the start mass uniformly over nodes whose centre lies within this of the start's.

    Returns:
        (M,) float64 belief summing to 1.
    """
    if start_node is None:
        return np.full(n_nodes, 1.0 / n_nodes)
    if not 0 <= start_node < n_nodes:
        raise BadInputError(f"node {start_node} is not in a map of {n_nodes} nodes", field="start_node")
    x = np.zeros(n_nodes)
    if radius_m > 0 and centres_m is not None:
        near = np.linalg.norm(centres_m - centres_m[start_node], axis=1) <= radius_m
        x[near] = 1.0
    x[start_node] = 1.0
    return np.asarray(x / x.sum(), dtype=np.float64)
