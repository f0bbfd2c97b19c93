"""Online localisation against a stored map ([SSLAM] III-B): one frame in, one position estimate out.

:class:`Localiser` holds the map (:class:`LocaliserMap`), the belief and the continuous track;
:meth:`Localiser.step` runs the vehicle camera's odometry step (:mod:`driftmap.core.localisation.motion`),
one HMM step of :mod:`driftmap.core.localisation.hmm` whose transition moves the belief by the distance
driven and whose prior is weighed by the turns driven against the map's turns every 2.5 m
(:mod:`driftmap.core.localisation.turns`), and the track update (:mod:`driftmap.core.localisation.track`),
and returns an :class:`Estimate`: b(i) (eq. 11), the
continuous position and heading, speed, and the one calibrated confidence that ``matched`` thresholds.
``docs/design/localiser.md`` explains the model. The batch CLI, the report and the live server use it the
same way; the live server keeps :meth:`Localiser.state` in its shared store between frames and calls
:meth:`Localiser.restore` on the next.

Lost detection and relocation (beyond the paper) judge b(i) against the other compared places: see
:mod:`driftmap.core.localisation.evidence`. With ``single_image=True`` there is no filter: every node is
compared and b(i) = argmin d.

SESAME ([SESAME], eq. 6): with ``sesame`` parameters only the query's salient pixels (Shannon entropy of the
raw frame) count in every node comparison; a query with almost none (a black frame) is compared whole.
"""

from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from driftmap.core.imaging.lens import Lens
from driftmap.core.imaging.params import SAD_DEFAULT, ImageParams, SadParams
from driftmap.core.imaging.views import thumbnails, undistorted_view
from driftmap.core.localisation import evidence, hmm, transitions, tunnels
from driftmap.core.localisation import track as localiser_track
from driftmap.core.localisation.map import LocaliserMap
from driftmap.core.localisation.motion import OdometryFeed
from driftmap.core.localisation.state import Estimate, LocaliserState
from driftmap.core.localisation.track import TRACK_DEFAULT, TrackParams, TrackState
from driftmap.core.localisation.turns import TURNS_DEFAULT, TurnHistory, TurnParams, turn_likelihood
from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.step import OdometryStep
from driftmap.core.sesame.masks import SesameParams, sesame_masks
from driftmap.core.types import F64, I64
from driftmap.errors import BadInputError

__all__ = ["Estimate", "Localiser", "LocaliserState"]

_PROBE_STRIDE = 7919  # a prime: probe k of frame s is node (s * n_probe + k) * stride mod M
_MIN_SALIENT_FRACTION = 0.02  # a query mask with fewer salient pixels than this is replaced by no mask


class Localiser:
    """Stateful HMM localiser: map and belief in, one frame at a time, estimates out.

    Args:
        lmap: the map.
        params: filter parameters (:data:`driftmap.core.localisation.hmm.DEFAULT`, :data:`~driftmap.core.localisation.hmm.PAPER`).
        sad_params: SAD shift ranges.
        image_params: pre-processing applied to frames that are not already thumbnails; None: the map's.
        single_image: no temporal filter (for ``--no-temporal`` comparisons).
        sesame: SESAME mask parameters ([SESAME] eq. 6); None compares whole images (holistic SAD).
        start_node: known start node; None starts with a global (uniform) belief.
        start_radius_m: spread the start over nodes within this of the start node, metres.
        camera: the vehicle's calibrated camera: its ground-plane odometry moves the belief by the distance
            driven and dead-reckons the continuous position (:mod:`driftmap.core.localisation.motion`); None
            localises by appearance alone (every estimate says ``odometry=False``).
        track_params: the continuous position track's noise model (:mod:`driftmap.core.localisation.track`).
        start_xy_m: the known start's survey point, metres (the track starts there); None: its node's centre.
        turn_params: the check of turns driven against the map's turns (:mod:`driftmap.core.localisation.turns`;
            needs odometry); None: no turn check.
        lens: query frames are taken in this lens's thumbnail view (:mod:`driftmap.core.imaging.views`), as the
            map's frames of that camera were; None: ``camera``'s lens (as recorded when there is none).
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
        camera: CameraModel | None = None,
        track_params: TrackParams = TRACK_DEFAULT,
        start_xy_m: tuple[float, float] | None = None,
        turn_params: TurnParams | None = TURNS_DEFAULT,
        lens: Lens | None = None,
    ) -> None:
        self.map = lmap
        self.lens = lens if lens is not None or camera is None else camera.lens
        self.turn_params = turn_params
        self.track_params = track_params
        self.odometry = None if camera is None or single_image else OdometryFeed(camera)
        self.params = params
        self.sad_params = sad_params
        self.image_params = lmap.image_params if image_params is None else image_params
        self.single_image = single_image
        self.sesame = sesame
        self.transitions = transitions.TransitionModel(
            lmap.adjacency_m, lmap.max_adjacency_m, params, steps=lmap.long_steps(params.min_a_t_m)
        )
        self._all = np.arange(lmap.n_nodes, dtype=np.int64)
        self._state = LocaliserState(hmm.initial_belief(lmap.n_nodes), float("nan"), 0, 0)
        self.reset(start_node, start_radius_m, start_xy_m)

    def reset(
        self,
        start_node: int | None = None,
        start_radius_m: float = 0.0,
        start_xy_m: tuple[float, float] | None = None,
    ) -> None:
        """Start again: peaked at ``start_node`` (within ``start_radius_m`` metres) or global when None; the
        continuous track starts at ``start_xy_m`` (default: the start node's centre), sd the radius."""
        belief = hmm.initial_belief(self.map.n_nodes, start_node, self.map.centres_m, start_radius_m)
        confirmed = (
            0 if start_node is None else self.params.confirm_frames
        )  # a known start needs no confirming
        track = TrackState.empty()
        if start_node is not None:
            xy = start_xy_m if start_xy_m is not None else tuple(self.map.centres_m[start_node])
            sd = max(start_radius_m, self.track_params.fix_sigma_m)
            track = TrackState.at((float(xy[0]), float(xy[1])), sd, trusted=True)
        # a known start is trusted as a distinct track until the views say otherwise (the running
        # distinctness forgets it within a few frames); a global start earns its confidence frame by frame
        node, distinct = (-1, 0.0) if start_node is None else (start_node, 1.0)
        self._state = LocaliserState(
            belief, float("nan"), 0, 0, confirmed, node=node, distinct=distinct, track=track
        )
        if self.odometry is not None:
            self.odometry.restore(np.zeros((0, 0), dtype=np.uint8), float("nan"))

    def state(self) -> LocaliserState:
        """The current state (a copy)."""
        s = self._state
        last = np.zeros((0, 0), dtype=np.uint8) if self.odometry is None else self.odometry.previous_frame()
        return replace(s, belief=s.belief.copy(), last_query=s.last_query.copy(), last_frame=last.copy())

    def restore(self, state: LocaliserState) -> None:
        """Continue from a saved state of a localiser on the same map."""
        if state.belief.shape != (self.map.n_nodes,):
            raise BadInputError(
                f"belief must be ({self.map.n_nodes},), got {state.belief.shape}", field="belief"
            )
        self._state = replace(state, belief=state.belief.copy(), last_query=state.last_query.copy())
        if self.odometry is not None:
            self.odometry.restore(state.last_frame, state.last_t_s)

    def thumbnail(self, frame: NDArray[np.generic]) -> NDArray[np.float32]:
        """(H, W) float32 query thumbnail: a floating frame of the map's thumbnail shape is taken as is."""
        shape = self.map.thumbs.shape[1:]
        if frame.dtype.kind == "f" and frame.shape == shape:
            return np.asarray(frame, dtype=np.float32)
        thumb = thumbnails(np.asarray(frame), self.image_params, self.lens)
        if thumb.shape != shape:
            raise BadInputError(f"frame pre-processes to {thumb.shape}, the map holds {shape}", field="frame")
        return thumb

    def query_mask(self, frame: NDArray[np.generic]) -> NDArray[np.bool_] | None:
        """(h, w) bool SESAME salient mask of a raw frame (in the lens's thumbnail view) at the thumbnail size;
        None without SESAME, for a frame that is already a thumbnail (no raw pixels to take entropy of) and
        for a frame with fewer than 2 % salient pixels (it is compared whole instead)."""
        if self.sesame is None or frame.dtype != np.uint8:
            return None
        mask = sesame_masks(undistorted_view(np.asarray(frame), self.lens), self.sesame, self.image_params)
        if mask.shape != self.map.thumbs.shape[1:] or mask.mean() < _MIN_SALIENT_FRACTION:
            return None
        return np.asarray(mask, dtype=bool)

    def _probes(self, steps: int) -> I64:
        n, m = self.params.n_probe, self.map.n_nodes
        return ((steps * n + np.arange(n, dtype=np.int64)) * _PROBE_STRIDE) % m

    def step(
        self,
        frame: NDArray[np.generic],
        t_s: float,
        mask: NDArray[np.bool_] | None = None,
        motion: OdometryStep | None = None,
    ) -> Estimate:
        """Localise one frame.

        Args:
            frame: (H, W) uint8 grey frame (or colour (H, W, 3)), pre-processed with ``image_params``; or an
                already pre-processed (h, w) float32 thumbnail of the map's thumbnail shape.
            t_s: the frame's timestamp, seconds; the gap to the previous frame sets A_t.
            mask: (h, w) bool salient mask of the query at the thumbnail size; None computes it from a raw
                frame when ``sesame`` is set (:meth:`query_mask`).
            motion: the vehicle's usable odometry step since the previous frame, measured elsewhere (the
                camera's odometry is then not run on this frame); None: the camera's odometry, when there is
                a camera.

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
            score = evidence.distinctness(d, float(d[best]))
            self._state = LocaliserState(s.belief, t_s, 0, s.steps + 1)
            x_m, y_m = lm.centres_m[best]
            return self._estimate(
                best, score, False, lm.n_nodes, t0, score, (x_m, y_m, math.nan), None, False, True
            )

        gap_s = t_s - s.last_t_s if np.isfinite(s.last_t_s) else 0.0
        if motion is None and self.odometry is not None:
            motion = self.odometry.step(frame, t_s)
        if not np.isfinite(s.last_t_s) or hmm.is_global(s.belief):
            prior = s.belief  # a global belief stays as it is (pi of a flat belief favours well-linked nodes)
        else:
            prior = self.transitions.predict_driven(s.belief, gap_s, motion)
        prior, turns = self._check_turns(prior, s.turns, motion)
        nodes = hmm.select_states(prior, p.n_t)
        probes = np.setdiff1d(self._probes(s.steps), nodes) if nodes.size < lm.n_nodes else nodes[:0]
        compared = np.r_[nodes, probes]
        d_all, refs = hmm.compare_references(query, lm.thumbs, lm.node_ptr, compared, self.sad_params, mask)
        gamma = hmm.observation(d_all[: nodes.size], p.p_t, p.epsilon)
        belief = hmm.hmm_update(prior, nodes, gamma, p.epsilon)
        far_m = 2.0 * self.transitions.reach_m(gap_s)
        best = int(np.argmax(belief))
        typical, near, elsewhere, far_best = evidence.judge(lm.adjacency_m, best, compared, d_all, far_m)
        if p.relocate_ratio > 0 and elsewhere >= p.relocate_ratio:
            belief = hmm.add_hypothesis(belief, far_best, p.relocate_share)  # the next frames decide
            best = far_best  # now the belief's peak: eq. 11 on the belief this frame leaves
            typical, near, elsewhere, far_best = evidence.judge(lm.adjacency_m, best, compared, d_all, far_m)
        score = float(belief[best])
        frame_distinct = min(max(1.0 - max(typical, elsewhere), 0.0), 1.0)
        distinct = evidence.track_distinct(s.node, s.distinct, best, frame_distinct, near, p.distinct_memory)
        not_distinct = typical > p.lost_distinct_ratio or elsewhere > p.lost_elsewhere_ratio
        lost = p.lost_frames > 0 and (score < p.lost_confidence or not_distinct)
        still = evidence.is_still(query, s.last_query, float(np.min(d_all, initial=np.inf)), p.still_ratio)
        moving = s.moving + (0 if still else 1)
        if lost and still and moving >= p.confirm_frames:
            lost_count = s.lost_count  # the same view again: no new evidence of being elsewhere
        else:
            lost_count = s.lost_count + 1 if lost else 0
        reported_lost = lost and lost_count >= min(p.lost_report_frames, p.lost_frames)
        raw = 0.0 if reported_lost else score * distinct
        confidence = 0.0 if reported_lost else hmm.calibrated(raw, p.calibration)
        fix = lm.place_fix(best, compared, d_all, refs, self.track_params.fix_reach_m)
        sure = confidence >= p.confidence_threshold
        track, moving_now, disagree = self._follow(
            s.track, motion, gap_s, best, fix, raw, still, s.node, sure
        )
        if disagree:
            confidence = 0.0
        elif reported_lost and motion is not None and track.trusted:
            # the views tell nothing, but the trusted track is dead-reckoned on: a position, not lost (b(i)
            # did not correct the track); its confidence is the views', low while they stay ambiguous
            reported_lost = False
            confidence = hmm.calibrated(score * distinct, p.calibration)
        node = best
        if p.lost_frames > 0 and lost_count >= p.lost_frames:
            belief, lost_count, moving = self._restart_belief(track, motion is not None), 0, 0
            node = -1
        self._state = LocaliserState(
            belief, t_s, lost_count, s.steps + 1, moving, query.copy(), node, distinct, track, turns=turns
        )
        return self._estimate(
            best,
            score,
            reported_lost,
            int(d_all.size),
            t0,
            distinct,
            track.wT,
            track,
            motion is not None,
            moving_now,
            confidence,
        )

    def _restart_belief(self, track: TrackState, dead_reckoned: bool) -> F64:
        """The belief after ``lost_frames`` lost frames in a row: over the nodes within the fix gate + 3 sd
        of a trusted track odometry dead-reckons (the views lost the place, not the vehicle), else global."""
        lm, tp = self.map, self.track_params
        if not (dead_reckoned and track.trusted and track.has_position):
            return hmm.initial_belief(lm.n_nodes)
        around = lm.nearest_node(float(track.wT[0]), float(track.wT[1]))
        radius_m = tp.gate_m + 3.0 * math.sqrt(track.var_m2)
        return hmm.initial_belief(lm.n_nodes, around, lm.centres_m, radius_m)

    def _check_turns(
        self, prior: F64, history: TurnHistory, motion: OdometryStep | None
    ) -> tuple[F64, TurnHistory]:
        """The prior weighed by the turn check (:mod:`driftmap.core.localisation.turns`) when this frame's step
        completes a sample of a driven window, and the driven path's history after the step (forgotten
        after an unusable step: the heading change of that frame is unknown)."""
        tp = self.turn_params
        if tp is None or motion is None:
            return prior, TurnHistory.empty()
        if motion.stationary:
            return prior, history
        history, turn = history.advance(motion.dx_m, motion.dtheta_rad, tp)
        if turn is None or hmm.is_global(prior):
            return prior, history
        weighed = prior * turn_likelihood(turn, self.map.turns(tp))
        total = float(weighed.sum())
        return (np.asarray(weighed / total, dtype=np.float64) if total > 0 else prior), history

    def _follow(
        self,
        track: TrackState,
        motion: OdometryStep | None,
        gap_s: float,
        best: int,
        fix_m: F64,
        raw: float,
        still: bool,
        last_node: int = -1,
        sure: bool = True,
    ) -> tuple[TrackState, bool, bool]:
        """The continuous track after this frame: moved by odometry, corrected by the place fix ``fix_m``
        (where the best-matching reference near b(i) was taken, :meth:`LocaliserMap.place_fix`) unless the
        frame is lost (``raw``, the uncalibrated ``score x distinct``, is 0), kept on the mapped tunnels around it
        (:mod:`driftmap.core.localisation.track`); whether the vehicle moves (odometry speed, else a changed
        view); and whether the track and b(i) disagree (a doubtful far b(i) the dead-reckoned track did not
        follow). Only a ``sure`` fix (its frame's confidence reaches the match threshold) counts as evidence
        of a wrong heading."""
        tp, lm = self.track_params, self.map
        track = localiser_track.predict(track, motion, gap_s, tp)
        disagree = False
        if raw > 0.0 or not track.has_position:  # a lost frame's b(i) says nothing
            confident = raw >= tp.fix_min_confidence
            travel_m = None if motion is None else abs(motion.dx_m)
            track, disagree = localiser_track.correct(
                track, fix_m, confident, motion is not None, tp, travel_m, steers=sure
            )
        if motion is not None:
            moving = not motion.stationary and abs(motion.dx_m) > tp.moving_mps * max(gap_s, 1e-3)
            if (
                moving
                and raw > 0.0
                and 0 <= last_node != best
                and best in evidence.near(lm.adjacency_m, last_node, tp.check_step_m)
            ):
                sign = math.copysign(1.0, motion.dx_m)
                track = localiser_track.check_heading(
                    track, lm.centres_m[last_node], lm.centres_m[best], sign, tp
                )
        else:
            moving = not still
        if lm.path_xy_m is not None and lm.path_segments.size and track.has_position:
            vertices, edges = lm.path_xy_m, lm.path_near(track.wT[:2], tp.snap_max_m)
        else:
            around = lm.nearest_node(float(track.wT[0]), float(track.wT[1]))
            vertices = lm.centres_m
            edges = lm.edges_near(np.r_[around, evidence.near(lm.adjacency_m, around, tp.snap_radius_m)])
        turning = motion is not None and abs(motion.dtheta_rad) > tp.turning_rad_per_m * max(
            abs(motion.dx_m), 0.05
        )
        snapped = tunnels.snap(track, vertices, edges, moving, tp, motion is not None, turning)
        return snapped, moving, disagree

    def _estimate(
        self,
        node: int,
        score: float,
        lost: bool,
        evaluated: int,
        t0: float,
        distinct: float,
        wT: F64 | tuple[float, float, float],
        track: TrackState | None,
        odometry: bool,
        moving: bool,
        confidence: float | None = None,
    ) -> Estimate:
        """The frame's :class:`Estimate`; ``confidence`` None: the calibrated ``score x distinct`` (0 lost)."""
        distinct = min(max(distinct, 0.0), 1.0)
        if confidence is None:
            confidence = 0.0 if lost else hmm.calibrated(score * distinct, self.params.calibration)
        speed = track.speed_mps if track is not None and odometry else math.nan
        return Estimate(
            node=node,
            x_m=float(wT[0]),
            y_m=float(wT[1]),
            score=score,
            matched=confidence >= self.params.confidence_threshold and not lost,
            lost=lost,
            evaluated_nodes=evaluated,
            ms=(time.perf_counter() - t0) * 1e3,
            distinct=distinct,
            confidence=confidence,
            yaw_rad=float(wT[2]),
            speed_mps=float(speed),
            moving=bool(moving),
            odometry=odometry,
        )
