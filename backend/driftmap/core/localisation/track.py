"""A localising vehicle's continuous position and heading along the mapped tunnels (beyond [SSLAM]).

The HMM (:mod:`driftmap.core.localisation.hmm`) answers *which place*: a node every N metres. Between and beyond node
centres this module keeps a metric track, a planar pose ``wT = (x_m, y_m, yaw_rad)`` in the survey frame
(x east, y north, yaw counter-clockwise from +x: the way the vehicle faces) with a position variance:

* **predict** (:func:`predict`): with a usable odometry step (eq. 1-2, :mod:`driftmap.core.localisation.motion`)
  the pose is composed with the step's ``prev_T_curr`` (rear-axle arc) and the variance grows with the step's
  ``sigma_xy_m`` plus ``step_sigma_frac`` of its length; without one the vehicle may have moved anywhere within
  ``free_speed_mps`` x the gap (a random walk), and heading is held. A vehicle whose odometry measured it
  moving coasts on at its running speed through an unusable step (blur, a dropped frame), the speed fading
  by ``coast_fade`` per such step and for at most ``coast_max_s`` of a long gap: holding it still would leave the track a step behind every time.
* **correct** (:func:`correct`): the place fix, the centre of the HMM's b(i) of a frame that is not lost,
  pulls the position with the Kalman gain ``var / (var + r)``, ``r = fix_sigma_m^2`` (a node centre is within
  half a node spacing of the vehicle: ``fix_sigma_m`` ~ N / sqrt(12) plus the centre's own scatter). The
  frames of one node give the same fix over and over, so with odometry a frame's fix counts as the share
  ``travel / fix_spacing_m`` of an independent one (``r`` divided by it): none while the vehicle stands,
  which would otherwise pull it to the centre of the node it stands in. A fix further
  than ``gate_m`` plus three standard deviations from the track re-anchors it there (a relocation, a
  restart; the heading becomes unknown again), unless the track is dead-reckoned by odometry and trusted (a
  confident fix or a known start confirmed it) and the frame is doubtful: then the track holds its course
  (for at most ``max_hold_m`` driven in a row: a vehicle standing still sees the same doubtful view again, no
  new evidence of being elsewhere) and the frame, whose place and track disagree, gets no confidence.
* **follow the tunnels** (:func:`driftmap.core.localisation.tunnels.snap`): the position is projected onto the nearest mapped edge around it
  (a segment of the mapped paths, :func:`driftmap.core.localisation.map.mapped_paths`, or without them of
  the edges between directly driven node centres) when it lies beside one within ``snap_max_m`` (with
  odometry, only onto edges within ``snap_max_turn_rad`` of the measured heading: a vehicle turning into a
  drawpoint or stub the map has no edge for leaves the tunnel it crossed), so
  positions and trails stay in the tunnels (past the end of every edge, at a dead end or a gap in the
  mapped edges, it is left as dead-reckoned); the
  heading is pulled towards the edge's direction (whichever of its two ways is nearer) while moving.
* **heading**: an unknown heading (after an anchor) is set, once the vehicle moves beside a mapped edge, to
  one of the edge's two directions, and checked (:func:`check_heading`) when b(i) next steps to a
  neighbouring node while odometry says the vehicle moves: a heading whose way of travel points against the
  step is turned by pi. While moving, the fixes' innovations along and across the direction of travel are
  summed with decay (``flip_memory``). A heading off by an angle t makes the prediction run away from the
  fixes: each innovation points along ``(cos t - 1, sin t)`` in the vehicle's frame (travel, left), so once
  the summed innovations are longer than ``flip_m`` and point backwards, ``t = 2 atan2(left, along) - pi``;
  the heading is turned by t when that exceeds ``turn_min_rad`` (pi: it faces the other way; about pi/2: it
  was set along a crossing tunnel, where no edge along it would ever pull it back). A right heading only
  sees the fixes' small lag and scatter; after a correction the position variance is raised so the fixes
  pull the track back quickly.

Speed comes from the odometry steps (signed metres over the frame gap, exponentially averaged); without
odometry it is unknown (NaN).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from driftmap.core.odometry.drive import compose
from driftmap.core.odometry.step import OdometryStep
from driftmap.core.types import F64

__all__ = ["TRACK_DEFAULT", "TrackParams", "TrackState", "check_heading", "correct", "predict", "wrap_angle"]


@dataclass(frozen=True)
class TrackParams:
    """The continuous track's noise model and gates."""

    fix_sigma_m: float = 3.0  # standard deviation of a place fix (b(i)'s centre) about the vehicle, metres
    step_sigma_frac: float = 0.03  # odometry position sd per metre driven, on top of the step's own sigma
    free_speed_mps: float = 3.0  # without odometry: position sd grows by this x the frame gap
    gate_m: float = 10.0  # a fix further than this + 3 sd from the track re-anchors it, metres
    flip_memory: float = 0.9  # per fix, the share of the heading-reversal evidence kept
    flip_m: float = 25.0  # the heading is corrected when that evidence is longer than this, metres
    turn_min_rad: float = 0.35  # ... by the angle it shows, when at least this (smaller: the pull's job)
    heading_pull: float = 0.05  # per moving frame, the share of the gap to the edge direction closed
    pull_max_rad: float = 0.25  # ... when the gap is at most this (more: the edge is another tunnel's)
    speed_memory: float = 0.5  # weight of the newest step in the running speed
    moving_mps: float = 0.15  # a vehicle whose odometry step is faster than this is moving, m/s
    fix_min_confidence: float = (
        0.3  # a far fix re-anchors a trusted track at this raw confidence (X x distinct)
    )
    snap_radius_m: float = 15.0  # without mapped paths: to edges of the nodes within this path length of it
    snap_max_m: float = 3.0  # ... when one is at most this far (further: off the mapped edges, left as is)
    snap_max_turn_rad: float = 0.6  # ... and only to edges within this of the track's heading (either way)
    max_hold_m: float = 7.5  # a trusted track holds its course against doubtful far fixes this far driven
    check_step_m: float = 7.5  # b(i) stepping to a node at most this far (path, and both near the track)
    # checks a new heading's way
    turning_rad_per_m: float = 0.03  # odometry turning sharper than this is a turn: no heading pull
    fix_spacing_m: float = 2.5  # with odometry: one independent fix per this much travel, metres
    coast_fade: float = 0.7  # per unusable odometry step, the share of the running speed the track keeps
    coast_max_s: float = (
        1.0  # ... and it coasts at most this long per step (a longer gap: it may have stopped)
    )
    fix_reach_m: float = 7.5  # the place fix: the best reference of the nodes this near b(i) (path), metres
    stray_m: float = 6.0  # a sure fix further than this from the track: the track has strayed, metres
    stray_frames: int = 5  # ... so many sure fixes in a row re-anchor it there
    scale_sd: float = 0.05  # prior sd of the odometry's scale factor (a camera's k_x, k_y off by this share)
    scale_walk_per_m: float = 1e-3  # ... its random walk, sd per square root of a metre driven
    scale_max_dev: float = 0.2  # ... the estimate stays within 1 -+ this

    def __post_init__(self) -> None:
        for name in ("fix_sigma_m", "free_speed_mps", "gate_m", "flip_m", "fix_spacing_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"TrackParams.{name} must be positive, got {getattr(self, name)}")
        for name in ("heading_pull", "speed_memory", "flip_memory", "coast_fade"):
            if not 0.0 < getattr(self, name) <= 1.0:
                raise ValueError(f"TrackParams.{name} must be in (0, 1], got {getattr(self, name)}")


TRACK_DEFAULT = TrackParams()


@dataclass(frozen=True, eq=False)
class TrackState:
    """The continuous track between frames.

    Attributes:
        wT: (3,) float64 ``[x_m, y_m, yaw_rad]`` survey frame; x, y NaN before the first fix, yaw NaN while
            unknown.
        var_m2: position variance (isotropic), square metres.
        speed_mps: signed running speed from odometry (negative: reversing); NaN when not measured.
        flip_m: evidence that the heading is wrong: the decaying sum of the fixes' innovations along the
            direction of travel, metres (negative: the fixes keep pulling the track back).
        trusted: a confident fix (or a known start) has confirmed the track since it was anchored; only a
            trusted dead-reckoned track holds its course against a doubtful far fix.
        held_m: metres driven while holding against doubtful far fixes, in a row.
        heading_checked: the heading, one of an edge's two ways when it was set, has been checked against
            the way b(i) stepped to a neighbouring node (:func:`check_heading`).
        flip_left_m: the same sum across the direction of travel (to its left), metres.
        strayed: sure fixes in a row further than ``stray_m`` from the track.
        scale: the odometry's estimated scale factor (true travel / measured travel).
        scale_var: its variance; NaN: the prior ``scale_sd ** 2``.
        scale_cov_m: covariance of the position along the heading and the scale, metres.
    """

    wT: F64
    var_m2: float
    speed_mps: float
    flip_m: float
    trusted: bool = False
    held_m: float = 0.0
    heading_checked: bool = False
    flip_left_m: float = 0.0
    strayed: int = 0
    scale: float = 1.0
    scale_var: float = math.nan
    scale_cov_m: float = 0.0

    @classmethod
    def empty(cls) -> TrackState:
        """No track yet."""
        return cls(np.full(3, np.nan), math.inf, math.nan, 0.0)

    @classmethod
    def at(cls, xy_m: tuple[float, float], sigma_m: float, trusted: bool = False) -> TrackState:
        """A track anchored at the survey point ``xy_m`` with sd ``sigma_m`` metres, heading unknown."""
        xy = np.asarray(xy_m, dtype=np.float64)
        return cls(np.r_[xy, np.nan], float(sigma_m) ** 2, math.nan, 0.0, trusted)

    def with_scale_of(self, other: TrackState) -> TrackState:
        """This track with ``other``'s odometry scale estimate (a property of the camera, kept when the
        track re-anchors; its correlation with the old position is dropped)."""
        return replace(self, scale=other.scale, scale_var=other.scale_var, scale_cov_m=0.0)

    @property
    def has_position(self) -> bool:
        return bool(np.isfinite(self.wT[0]))

    @property
    def has_heading(self) -> bool:
        return bool(np.isfinite(self.wT[2]))

    def to_arrays(self) -> F64:
        """(14,) float64 packed for the localiser's stored state."""
        packed = np.r_[
            self.wT,
            self.var_m2,
            self.speed_mps,
            self.flip_m,
            float(self.trusted),
            self.held_m,
            float(self.heading_checked),
            self.flip_left_m,
            self.strayed,
            self.scale,
            self.scale_var,
            self.scale_cov_m,
        ]
        return np.asarray(packed, dtype=np.float64)

    @classmethod
    def from_arrays(cls, packed: F64) -> TrackState:
        """Inverse of :meth:`to_arrays`; 8 to 11 values (stored before the heading check, the sideways
        evidence, the stray count or the scale) are read with those as checked, 0 and the prior; other
        sizes: no track."""
        a = np.asarray(packed, dtype=np.float64).ravel()
        if a.size not in (8, 9, 10, 11, 14):
            return cls.empty()
        checked = bool(a[8]) if a.size >= 9 else True
        left = float(a[9]) if a.size >= 10 else 0.0
        strayed = int(a[10]) if a.size >= 11 else 0
        scale = (float(a[11]), float(a[12]), float(a[13])) if a.size == 14 else (1.0, math.nan, 0.0)
        base = (float(a[3]), float(a[4]), float(a[5]), bool(a[6]), float(a[7]))
        return cls(a[:3].copy(), *base, checked, left, strayed, *scale)


def wrap_angle(angle_rad: float) -> float:
    """``angle_rad`` wrapped to (-pi, pi]."""
    return math.atan2(math.sin(angle_rad), math.cos(angle_rad))


def predict(state: TrackState, step: OdometryStep | None, gap_s: float, params: TrackParams) -> TrackState:
    """Move the track by one frame: by the odometry ``step`` when given, else a random walk.

    Args:
        state: the track after the previous frame.
        step: the usable odometry step between the frames, or None.
        gap_s: the frame gap, seconds.
        params: noise model.
    """
    if not state.has_position:
        return state
    gap = max(gap_s, 0.0)
    if step is None:
        var = state.var_m2 + (params.free_speed_mps * gap) ** 2
        if not (state.has_heading and math.isfinite(state.speed_mps)):
            return replace(state, var_m2=var, speed_mps=math.nan)
        # an unusable step of a vehicle measured moving: it coasts on at its running speed, which fades
        wT = state.wT.copy()
        coast_m = state.speed_mps * min(gap, params.coast_max_s)
        wT[:2] += coast_m * np.array([math.cos(wT[2]), math.sin(wT[2])])
        return replace(state, wT=wT, var_m2=var, speed_mps=state.speed_mps * params.coast_fade)
    sd = step.sigma_xy_m + params.step_sigma_frac * abs(step.dx_m)
    k = state.scale
    dx = k * step.dx_m
    speed = dx / gap if gap > 0 else 0.0
    a = params.speed_memory
    speed = speed if not math.isfinite(state.speed_mps) else (1 - a) * state.speed_mps + a * speed
    if not state.has_heading:
        return replace(state, var_m2=state.var_m2 + sd * sd, speed_mps=speed)
    x_m, y_m, yaw_rad = step.prev_T_curr
    wT = compose(state.wT, (k * x_m, k * y_m, yaw_rad))
    # the position along the heading moves by scale x dx: its error grows with the scale's, with which it
    # is correlated (the fixes' innovations along the heading then tell the scale)
    k_var = state.scale_var if math.isfinite(state.scale_var) else params.scale_sd**2
    var = state.var_m2 + sd * sd + 2.0 * step.dx_m * state.scale_cov_m + step.dx_m**2 * k_var
    cov = state.scale_cov_m + step.dx_m * k_var
    k_var += params.scale_walk_per_m**2 * abs(step.dx_m)
    return replace(state, wT=wT, var_m2=var, speed_mps=speed, scale_var=k_var, scale_cov_m=cov)


def correct(
    state: TrackState,
    fix_m: F64,
    confident: bool,
    dead_reckoned: bool,
    params: TrackParams,
    travel_m: float | None = None,
    steers: bool = True,
) -> tuple[TrackState, bool]:
    """Fuse the place fix (2,) ``fix_m`` (survey metres, b(i)'s centre of a frame not lost) into the track.

    Within the gate the fix pulls the track with the Kalman gain (a ``confident`` fix, or one that
    ``steers``, makes the track trusted). Beyond it the track re-anchors at the fix unless the track is trusted and ``dead_reckoned`` by
    odometry and the frame is doubtful: such a track keeps its course, for at most ``max_hold_m`` driven in a
    row (then the place recognition, consistently elsewhere, wins). The first fix anchors a track that has
    none.

    ``travel_m`` is the distance driven since the last frame by odometry (None without odometry: every
    frame's fix counts whole). Only a fix that ``steers`` (a sure one) adds to the evidence of a wrong
    heading: doubtful fixes metres off, while the views are ambiguous, would turn a right heading. A sure
    fix further than ``stray_m`` from a ``dead_reckoned`` track (inside the gate) means it has strayed, by a wrong
    heading or odometry run away: the frame's position is not vouched for, and ``stray_frames`` of them in a
    row re-anchor the track at the fix.

    Returns:
        The new track, and whether it disagrees with the fix (a doubtful far fix was not followed, or a
        sure fix lies further than ``stray_m`` from it: the position reported is the track's, and the frame
        gets no confidence).
    """
    fix = np.asarray(fix_m, dtype=np.float64)
    r2 = params.fix_sigma_m**2
    # the fixes of consecutive frames are one node's centre over and over: with odometry they count as one
    # independent fix per fix_spacing_m driven (none while standing), else each frame's fix is pulled
    # towards many times and the track drifts to the centre of the node it stands in
    # (a track without a heading does not move with odometry: every fix counts whole, as without it)
    dead_reckons = travel_m is not None and state.has_heading
    r2_pull = r2 * params.fix_spacing_m / max(travel_m or 0.0, 1e-9) if dead_reckons else r2
    if not state.has_position:
        return TrackState.at((float(fix[0]), float(fix[1])), params.fix_sigma_m, confident), False
    off = float(np.hypot(*(fix - state.wT[:2])))
    if off > params.gate_m + 3.0 * math.sqrt(state.var_m2 + r2):
        if dead_reckoned and state.trusted and not confident and state.held_m < params.max_hold_m:
            return replace(state, held_m=state.held_m + (travel_m or 0.0)), True
        anchored = TrackState.at((float(fix[0]), float(fix[1])), params.fix_sigma_m, confident)
        return replace(anchored.with_scale_of(state), speed_mps=state.speed_mps), False
    state = replace(state, trusted=state.trusted or confident or steers, held_m=0.0)
    strayed = state.strayed + 1 if dead_reckoned and steers and off > params.stray_m else 0
    if strayed >= params.stray_frames:  # sure fixes keep saying the track is elsewhere: it is
        anchored = TrackState.at((float(fix[0]), float(fix[1])), params.fix_sigma_m, True)
        return replace(anchored.with_scale_of(state), speed_mps=state.speed_mps), False
    total = state.var_m2 + max(r2_pull, r2)
    gain = state.var_m2 / total
    wT = state.wT.copy()
    innovation = fix - wT[:2]
    wT[:2] += gain * innovation
    var, flip, left = (1.0 - gain) * state.var_m2, state.flip_m, state.flip_left_m
    moving = math.isfinite(state.speed_mps) and abs(state.speed_mps) > params.moving_mps
    scale, k_var, cov = _correct_scale(state, innovation, total, dead_reckons and steers and moving, params)
    if steers and state.has_heading and moving:
        ahead = math.copysign(1.0, state.speed_mps) * np.array([math.cos(wT[2]), math.sin(wT[2])])
        flip = params.flip_memory * flip + float(innovation @ ahead)
        left = params.flip_memory * left + float(innovation @ np.array([-ahead[1], ahead[0]]))
        if flip < 0.0 and math.hypot(flip, left) > params.flip_m:  # the fixes keep pulling it back
            turn = wrap_angle(2.0 * math.atan2(left, flip) - math.pi)  # the heading error they show
            if abs(turn) >= params.turn_min_rad:
                wT[2], flip, left, cov = wrap_angle(wT[2] + turn), 0.0, 0.0, 0.0
                var = max(var, (2.0 * params.fix_sigma_m) ** 2)  # it ran the wrong way: let the fixes pull
    corrected = replace(state, wT=wT, var_m2=var, flip_m=flip, flip_left_m=left, strayed=strayed, scale=scale)
    return replace(corrected, scale_var=k_var, scale_cov_m=cov), strayed > 0


def _correct_scale(
    state: TrackState, innovation_m: F64, total_var_m2: float, learns: bool, params: TrackParams
) -> tuple[float, float, float]:
    """The odometry scale, its variance and its covariance with the position along the heading after a fix
    whose (2,) ``innovation_m`` (fix - track) had the variance ``total_var_m2``: the Kalman update of the
    scale through its correlation with the position (a track that keeps lagging its fixes drives further
    than its odometry says). Only a fix that ``learns`` (sure, with odometry, the vehicle moving) moves the
    scale; doubtful fixes metres off, while the views are ambiguous, would teach it a wrong one."""
    k_var = state.scale_var if math.isfinite(state.scale_var) else params.scale_sd**2
    cov = state.scale_cov_m
    gain = state.var_m2 / total_var_m2
    if not (learns and state.has_heading and math.isfinite(cov)):
        return state.scale, k_var, cov * (1.0 - gain)
    along = float(innovation_m @ np.array([math.cos(state.wT[2]), math.sin(state.wT[2])]))
    lo, hi = 1.0 - params.scale_max_dev, 1.0 + params.scale_max_dev
    scale = min(max(state.scale + cov / total_var_m2 * along, lo), hi)
    return scale, max(k_var - cov * cov / total_var_m2, 1e-8), cov * (1.0 - gain)


def check_heading(
    state: TrackState, from_m: F64, to_m: F64, travel_sign: float, params: TrackParams
) -> TrackState:
    """Check an unchecked heading against b(i)'s step from the node centred at (2,) ``from_m`` to a
    neighbour centred at ``to_m`` (survey metres) while the vehicle drove forwards (``travel_sign`` +1) or
    backwards (-1): a heading whose way of travel points against the step is turned by pi and the position
    variance raised, as a flip (:func:`correct`), so the fixes pull back what it ran the wrong way.

    An edge gives a heading up to its two ways; waiting for the fixes' innovations to say it is the wrong
    one takes a dozen frames of running the wrong way, one node step settles it. Only the first step after
    the heading was set counts (later, b(i) lagging a node behind would look like a step backwards), and only
    one between nodes centred within ``check_step_m`` of the track (a step of a b(i) elsewhere, still
    settling after a global start, says nothing about the way the track drives).
    """
    if state.heading_checked or not state.has_heading or travel_sign == 0.0:
        return state
    ends = np.stack([np.asarray(from_m, dtype=np.float64), np.asarray(to_m, dtype=np.float64)])
    if np.max(np.hypot(*(ends - state.wT[:2]).T)) > params.check_step_m:
        return state  # b(i) is elsewhere than the track: its step says nothing about the track's way
    step = ends[1] - ends[0]
    if not np.any(step):
        return state
    ahead = travel_sign * np.array([math.cos(state.wT[2]), math.sin(state.wT[2])])
    if float(ahead @ step) >= 0.0:
        return replace(state, heading_checked=True)
    wT = state.wT.copy()
    wT[2] = wrap_angle(wT[2] + math.pi)
    var = max(state.var_m2, (2.0 * params.fix_sigma_m) ** 2)
    return replace(state, wT=wT, var_m2=var, flip_m=0.0, heading_checked=True, scale_cov_m=0.0)
