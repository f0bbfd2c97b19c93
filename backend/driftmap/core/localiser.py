"""Online localisation against a stored map (paper 000 III-B): one frame in, one place estimate out.

:class:`Localiser` holds the map (:class:`LocaliserMap`) and the belief; :meth:`Localiser.step` runs one HMM
step of :mod:`driftmap.core.hmm` and returns an :class:`Estimate` (eq. 11 best node, eq. 12 match flag).
The batch CLI and the live server use it the same way; the live server keeps :meth:`Localiser.state` in its
shared store between frames and calls :meth:`Localiser.restore` on the next.

Lost detection (beyond the paper): a frame is lost when the confidence X_i(b(i)) is below ``lost_confidence``
or the believed place does not look distinctly better than somewhere else: d(i, b(i)) is above
``lost_elsewhere_ratio`` times the least d of the compared nodes (evaluated nodes and a few rotating probe
nodes) more than two frame reaches (2 A_t) of path away from b(i), or above ``lost_distinct_ratio`` times the
median d of the compared nodes. The test is relative to other places of the same map, so it holds in mines
where every tunnel looks much alike (d of the right place only a few per cent below an unrelated one's). A
right track fails this test on single frames (on the medium simulated sites 7.6-8.8 % of all frames were right
but failed it), so an estimate is reported lost only once ``lost_report_frames`` lost frames in a row are
counted; after ``lost_frames`` the belief becomes uniform, so the next frame searches the whole map. A vehicle
that stands where the map's views match poorly looks lost frame after frame, but it shows the same view again
and again: a "still" frame (its view changed less than ``still_ratio`` times its least d to the map since the
previous frame) adds no evidence of being elsewhere, so once the belief has followed ``confirm_frames`` moving
frames since its last global start, still lost frames leave the count where it was (and are reported lost only
if it had reached ``lost_report_frames``). With ``single_image=True`` there is no filter: every node is
compared and b(i) = argmin d.

Relocation (beyond the paper): a compared far node (as above) whose d is at least ``relocate_ratio`` times
below d(i, b(i)) gets ``relocate_share`` of the belief after the update, a second hypothesis that the next
frames confirm or drop. It is then the belief's peak, and the frame reports it (eq. 11 on the belief the
frame leaves, so the estimate and the stored state agree; the lost test and distinctness are those of the new
b(i)). A belief stuck on a look-alike can fail the lost test on most frames and still never reach
``lost_frames`` in a row; when a probe shows the true place clearly better, this moves it.

Transitions (eq. 9-10) also let the belief take every direct step between two nodes in one frame, however
long (:func:`driftmap.core.hmm.long_steps`): node spacing is uneven at junctions and merges, and a step
longer than the reach A_t would otherwise be a wall the belief can never cross.

SESAME (paper 001, eq. 6): with ``sesame`` parameters the query's Shannon-entropy salient mask is computed
from the raw frame and only salient query pixels count in every node comparison, normalised by their number
in the overlap. A query with almost no salient pixel (a black or washed-out frame) falls back to the plain
holistic SAD, so it still gets scores.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from driftmap.core import hmm
from driftmap.core.images import preprocess
from driftmap.core.localiser_map import LocaliserMap
from driftmap.core.params import SAD_DEFAULT, ImageParams, SadParams
from driftmap.core.saliency import SesameParams, sesame_masks
from driftmap.errors import BadInputError

__all__ = ["Estimate", "Localiser", "LocaliserState"]

F64 = NDArray[np.float64]
I64 = NDArray[np.int64]
_PROBE_STRIDE = 7919  # a prime: probe k of frame s is node (s * n_probe + k) * stride mod M
_MIN_SALIENT_FRACTION = 0.02  # a query mask with fewer salient pixels than this is replaced by no mask


@dataclass(frozen=True)
class Estimate:
    """The place estimate of one frame.

    Attributes:
        node: b(i), the best node (eq. 11).
        x_m: its centre's x, survey frame, metres.
        y_m: its centre's y, survey frame, metres.
        score: X_i(b(i)) in [0, 1]; single-image mode: 1 - d_best / median d over the map.
        matched: eq. 12, ``score >= x_thresh``, and the frame is not lost.
        lost: the filter is lost: this frame and the ones before it failed the lost test, at least
            ``lost_report_frames`` counted in a row (it re-initialises after ``lost_frames``).
        evaluated_nodes: number of nodes compared with the query this frame.
        ms: wall time of the step, milliseconds.
        distinct: how much better the track's frames match their b than anywhere else: this frame's
            ``1 - d(i, b(i)) / d_other`` clipped to [0, 1], with d_other the least d of the compared far nodes
            (the lost test's; the median d of the compared nodes when it is lower or no far node was
            compared), averaged exponentially (weight ``HmmParams.distinct_memory``, starting from 0) over
            the frames since b last jumped further than two frame reaches or the belief started globally
            (single-image mode: ``score``).
    """

    node: int
    x_m: float
    y_m: float
    score: float
    matched: bool
    lost: bool
    evaluated_nodes: int
    ms: float
    distinct: float = 0.0

    @property
    def confidence(self) -> float:
        """``score x distinct`` in [0, 1]: the belief is on b(i) *and* the track's views look like it.

        The posterior X_i(b(i)) alone can be high because the motion prior keeps it there while the view
        matches b(i) no better than anywhere else (a vehicle leaving a poorly mapped area towards a
        look-alike); ranking frames by this product keeps those below frames that show their place. The
        distinctness is measured against the best-matching far node, not only a typical one: a view that
        matches another part of the mine as well is ambiguous however well it matches b(i). It is averaged
        along the track because a single frame's is noisy (a right frame's is often as low as a
        look-alike's), while a look-alike stays barely better frame after frame; a track that has just
        begun (a jump, a global start) has no history yet and starts from 0.
        """
        return self.score * self.distinct


@dataclass(frozen=True, eq=False)
class LocaliserState:
    """The localiser's belief between frames, small enough for a shared store.

    Attributes:
        belief: (M,) float64 X_{i-1}, sums to 1.
        last_t_s: timestamp of the last frame, seconds; NaN before the first.
        lost_count: lost frames in a row so far.
        steps: frames processed (drives the probe rotation).
        moving: frames with a changed view since the last global start (uniform belief).
        last_query: (h, w) float32 thumbnail of the last frame; (0, 0) before the first.
        node: b(i) of the last frame; -1 before the first and after a global start.
        distinct: the track's running distinctness at the last frame (:attr:`Estimate.distinct`).
    """

    belief: F64
    last_t_s: float
    lost_count: int
    steps: int
    moving: int = 0
    last_query: NDArray[np.float32] = field(default_factory=lambda: np.zeros((0, 0), dtype=np.float32))
    node: int = -1
    distinct: float = 0.0

    def to_arrays(self) -> dict[str, NDArray[np.generic]]:
        """Named arrays (scalars as 0-d) for the store."""
        return {
            "belief": np.asarray(self.belief, dtype=np.float64),
            "last_t_s": np.asarray(self.last_t_s, dtype=np.float64),
            "lost_count": np.asarray(self.lost_count, dtype=np.int64),
            "steps": np.asarray(self.steps, dtype=np.int64),
            "moving": np.asarray(self.moving, dtype=np.int64),
            "last_query": np.asarray(self.last_query, dtype=np.float32),
            "node": np.asarray(self.node, dtype=np.int64),
            "distinct": np.asarray(self.distinct, dtype=np.float64),
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray[np.generic]]) -> LocaliserState:
        """Rebuild a state from :meth:`to_arrays` output (a state stored before ``moving``, ``node`` or
        ``distinct`` existed starts those afresh)."""
        try:
            return cls(
                belief=np.array(arrays["belief"], dtype=np.float64),
                last_t_s=float(arrays["last_t_s"]),
                lost_count=int(arrays["lost_count"]),
                steps=int(arrays["steps"]),
                moving=int(arrays.get("moving", 0)),
                last_query=np.array(arrays.get("last_query", np.zeros((0, 0))), dtype=np.float32),
                node=int(arrays.get("node", -1)),
                distinct=float(arrays.get("distinct", 0.0)),
            )
        except KeyError as exc:
            raise BadInputError("stored localiser state is missing an array", field=str(exc.args[0])) from exc


class Localiser:
    """Stateful HMM localiser: map and belief in, one frame at a time, estimates out.

    Args:
        lmap: the map.
        params: filter parameters (:data:`driftmap.core.hmm.DEFAULT`, :data:`~driftmap.core.hmm.PAPER`).
        sad_params: SAD shift ranges.
        image_params: pre-processing applied to frames that are not already thumbnails; None: the map's.
        single_image: no temporal filter (for ``--no-temporal`` comparisons).
        sesame: SESAME mask parameters (paper 001 eq. 6); None compares whole images (holistic SAD).
        start_node: known start node; None starts with a global (uniform) belief.
        start_radius_m: spread the start over nodes within this of the start node, metres.
    """

    def __init__(
        self,
        lmap: LocaliserMap,
        params: hmm.HmmParams = hmm.DEFAULT,
        sad_params: SadParams = SAD_DEFAULT,
        image_params: ImageParams | None = None,
        *,
        single_image: bool = False,
        sesame: SesameParams | None = None,
        start_node: int | None = None,
        start_radius_m: float = 0.0,
    ) -> None:
        self.map = lmap
        self.params = params
        self.sad_params = sad_params
        self.image_params = lmap.image_params if image_params is None else image_params
        self.single_image = single_image
        self.sesame = sesame
        self.transitions = hmm.TransitionModel(
            lmap.adjacency_m, lmap.max_adjacency_m, params, steps=lmap.long_steps(params.min_a_t_m)
        )
        self._all = np.arange(lmap.n_nodes, dtype=np.int64)
        self._state = LocaliserState(hmm.initial_belief(lmap.n_nodes), float("nan"), 0, 0)
        self.reset(start_node, start_radius_m)

    def reset(self, start_node: int | None = None, start_radius_m: float = 0.0) -> None:
        """Start again: peaked at ``start_node`` (within ``start_radius_m`` metres) or global when None."""
        belief = hmm.initial_belief(self.map.n_nodes, start_node, self.map.centres_m, start_radius_m)
        confirmed = (
            0 if start_node is None else self.params.confirm_frames
        )  # a known start needs no confirming
        self._state = LocaliserState(belief, float("nan"), 0, 0, confirmed)

    def state(self) -> LocaliserState:
        """The current state (a copy)."""
        s = self._state
        return replace(s, belief=s.belief.copy(), last_query=s.last_query.copy())

    def restore(self, state: LocaliserState) -> None:
        """Continue from a saved state of a localiser on the same map."""
        if state.belief.shape != (self.map.n_nodes,):
            raise BadInputError(
                f"belief must be ({self.map.n_nodes},), got {state.belief.shape}", field="belief"
            )
        self._state = replace(state, belief=state.belief.copy(), last_query=state.last_query.copy())

    def thumbnail(self, frame: NDArray[np.generic]) -> NDArray[np.float32]:
        """(H, W) float32 query thumbnail: a floating frame of the map's thumbnail shape is taken as is."""
        shape = self.map.thumbs.shape[1:]
        if frame.dtype.kind == "f" and frame.shape == shape:
            return np.asarray(frame, dtype=np.float32)
        thumb = preprocess(np.asarray(frame), self.image_params)
        if thumb.shape != shape:
            raise BadInputError(f"frame pre-processes to {thumb.shape}, the map holds {shape}", field="frame")
        return thumb

    def query_mask(self, frame: NDArray[np.generic]) -> NDArray[np.bool_] | None:
        """(h, w) bool SESAME salient mask of a raw frame at the thumbnail size; None without SESAME.

        None too for a frame that is already a thumbnail (no raw pixels to take entropy of) and for a frame
        with fewer than 2 % salient pixels (it is compared whole instead).
        """
        if self.sesame is None or frame.dtype != np.uint8:
            return None
        mask = sesame_masks(np.asarray(frame), self.sesame, self.image_params)
        if mask.shape != self.map.thumbs.shape[1:] or mask.mean() < _MIN_SALIENT_FRACTION:
            return None
        return np.asarray(mask, dtype=bool)

    def _probes(self, steps: int) -> I64:
        n, m = self.params.n_probe, self.map.n_nodes
        return ((steps * n + np.arange(n, dtype=np.int64)) * _PROBE_STRIDE) % m

    def step(self, frame: NDArray[np.generic], t_s: float, mask: NDArray[np.bool_] | None = None) -> Estimate:
        """Localise one frame.

        Args:
            frame: (H, W) uint8 grey frame (or colour (H, W, 3)), pre-processed with ``image_params``; or an
                already pre-processed (h, w) float32 thumbnail of the map's thumbnail shape.
            t_s: the frame's timestamp, seconds; the gap to the previous frame sets A_t.
            mask: (h, w) bool salient mask of the query at the thumbnail size; None computes it from a raw
                frame when ``sesame`` is set (:meth:`query_mask`).

        Returns:
            The :class:`Estimate`.
        """
        t0 = time.perf_counter()
        query = self.thumbnail(frame)
        if mask is None:
            mask = self.query_mask(frame)
        elif mask.shape != query.shape:
            raise BadInputError(f"mask must be {query.shape}, got {mask.shape}", field="mask")
        lm, p, s = self.map, self.params, self._state
        if self.single_image:
            d = hmm.compare_nodes(query, lm.thumbs, lm.node_ptr, self._all, self.sad_params, mask)
            best = int(np.argmin(d))
            score = self._distinctness(d, float(d[best]))
            self._state = LocaliserState(s.belief, t_s, 0, s.steps + 1)
            return self._estimate(best, score, False, lm.n_nodes, t0, score)

        gap_s = t_s - s.last_t_s if np.isfinite(s.last_t_s) else 0.0
        if not np.isfinite(s.last_t_s) or hmm.is_global(s.belief):
            prior = s.belief  # a global belief searches the whole map (pi would favour well-linked nodes)
        else:
            prior = self.transitions.predict(s.belief, gap_s)
        nodes = hmm.select_states(prior, p.n_t)
        probes = np.setdiff1d(self._probes(s.steps), nodes) if nodes.size < lm.n_nodes else nodes[:0]
        d_all = hmm.compare_nodes(query, lm.thumbs, lm.node_ptr, np.r_[nodes, probes], self.sad_params, mask)
        gamma = hmm.observation(d_all[: nodes.size], p.p_t, p.epsilon)
        belief = hmm.hmm_update(prior, nodes, gamma, p.epsilon)
        compared = np.r_[nodes, probes]
        far_m = 2.0 * self.transitions.reach_m(gap_s)
        best = int(np.argmax(belief))
        typical, near, elsewhere, far_best = self._judge(best, compared, d_all, far_m)
        if p.relocate_ratio > 0 and elsewhere >= p.relocate_ratio:
            belief = hmm.add_hypothesis(belief, far_best, p.relocate_share)  # the next frames decide
            best = far_best  # now the belief's peak: eq. 11 on the belief this frame leaves
            typical, near, elsewhere, far_best = self._judge(best, compared, d_all, far_m)
        score = float(belief[best])
        frame_distinct = min(max(1.0 - max(typical, elsewhere), 0.0), 1.0)
        distinct = self._track_distinct(s, best, frame_distinct, near)
        not_distinct = typical > p.lost_distinct_ratio or elsewhere > p.lost_elsewhere_ratio
        lost = p.lost_frames > 0 and (score < p.lost_confidence or not_distinct)
        still = self._is_still(query, s.last_query, float(np.min(d_all, initial=np.inf)))
        moving = s.moving + (0 if still else 1)
        if lost and still and moving >= p.confirm_frames:
            lost_count = s.lost_count  # the same view again: no new evidence of being elsewhere
        else:
            lost_count = s.lost_count + 1 if lost else 0
        reported_lost = lost and lost_count >= min(p.lost_report_frames, p.lost_frames)
        node = best
        if p.lost_frames > 0 and lost_count >= p.lost_frames:
            belief, lost_count, moving = hmm.initial_belief(lm.n_nodes), 0, 0  # re-initialise globally
            node = -1
        self._state = LocaliserState(
            belief, t_s, lost_count, s.steps + 1, moving, query.copy(), node, distinct
        )
        return self._estimate(best, score, reported_lost, int(d_all.size), t0, distinct)

    def _judge(
        self, best: int, compared: I64, d_all: NDArray[np.floating], far_m: float
    ) -> tuple[float, I64, float, int]:
        """How ``best`` compares with the other compared nodes: (d(b) / median d, the nodes within ``far_m``
        metres of path of it, :meth:`_elsewhere`'s ratio and far node)."""
        at_best = d_all[compared == best]
        d_here = float(at_best[0]) if at_best.size else float(np.min(d_all, initial=np.inf))
        near = self._near(best, far_m)
        elsewhere, far_best = self._elsewhere(compared, d_all, best, d_here, near)
        return 1.0 - self._distinctness(d_all, d_here), near, elsewhere, far_best

    def _near(self, best: int, far_m: float) -> I64:
        """(k,) int64 the nodes within ``far_m`` metres of path of ``best`` (two frame reaches: the same place)."""
        adj = self.map.adjacency_m
        row = slice(adj.indptr[best], adj.indptr[best + 1])
        return np.asarray(adj.indices[row][adj.data[row] <= far_m], dtype=np.int64)

    def _track_distinct(self, s: LocaliserState, best: int, distinct: float, near: I64) -> float:
        """The running distinctness of the track that ends at ``best``: this frame's ``distinct`` averaged
        exponentially (weight ``distinct_memory``) with the last frame's running value when the last b(i) is
        ``best`` or one of its ``near`` nodes; with 0 after a jump or a global start (a new track earns its
        confidence frame by frame)."""
        a = self.params.distinct_memory
        same_track = s.node >= 0 and (best == s.node or s.node in near)
        return (1.0 - a) * (s.distinct if same_track else 0.0) + a * distinct

    @staticmethod
    def _elsewhere(
        compared: I64, d: NDArray[np.floating], best: int, d_here: float, near: I64
    ) -> tuple[float, int]:
        """(d(b(i)) / least d of the compared nodes that are neither ``best`` nor ``near`` it, that node);
        (0, -1) if there is none."""
        far = ~np.isin(compared, near) & (compared != best) & np.isfinite(d)
        if not far.any():
            return 0.0, -1
        k = int(np.argmin(np.where(far, d, np.inf)))
        d_far = float(d[k])
        ratio = d_here / d_far if d_far > 0 and np.isfinite(d_here) else float("inf")
        return ratio, int(compared[k])

    def _is_still(self, query: NDArray[np.float32], last: NDArray[np.float32], d_least: float) -> bool:
        """True when the view barely changed since the last frame: mean |query - last| below ``still_ratio``
        x the least d of this frame to the map (the vehicle stands; a moving camera changes its view about as
        much as it differs from the best reference)."""
        ratio = self.params.still_ratio
        if ratio <= 0 or last.shape != query.shape or not np.isfinite(d_least):
            return False
        return float(np.mean(np.abs(query - last))) < ratio * d_least

    @staticmethod
    def _distinctness(d: NDArray[np.floating], d_best: float) -> float:
        """1 - d_best / median of the finite scores: 0 when the best is typical, near 1 when it stands out."""
        finite = d[np.isfinite(d)]
        if finite.size == 0 or not np.isfinite(d_best):
            return 0.0
        med = float(np.median(finite))
        return 1.0 - d_best / med if med > 0 else 0.0

    def _estimate(
        self, node: int, score: float, lost: bool, evaluated: int, t0: float, distinct: float
    ) -> Estimate:
        x_m, y_m = self.map.centres_m[node]
        return Estimate(
            node=node,
            x_m=float(x_m),
            y_m=float(y_m),
            score=score,
            matched=score >= self.params.x_thresh and not lost,
            lost=lost,
            evaluated_nodes=evaluated,
            ms=(time.perf_counter() - t0) * 1e3,
            distinct=min(max(distinct, 0.0), 1.0),
        )
