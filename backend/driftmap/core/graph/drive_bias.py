"""Self-calibration of each drive's odometry from the optimised map (beyond the paper).

Ground-plane odometry inherits three systematic errors from its camera calibration, and none averages
out along a drive:

* **Scale.** A camera height or pitch off by a percent makes every step a percent too long or short.
* **Heading rate.** A camera looking a fraction of a degree off the vehicle axis sees the floor slide
  sideways as the vehicle drives straight; the odometry reads the slide as turning, so the heading drifts
  by a fixed angle per metre of forward travel (opposite when reversing).
* **Turn gain.** A rotation centre (lever) off its true place, tyre slip or an articulated frame make
  every turn a few percent too sharp or too wide; unlike the heading rate, the error follows the turning,
  not the travel (the classic differential-drive calibration's wheelbase error).

Groundings and loop closures reveal all three: after an optimisation, the optimised trajectory turns and
stretches less or more than the odometry said, consistently. :func:`estimate_bias` fits one scale, one
heading rate and one turn gain per drive by comparing the raw odometry with the optimised poses over
windows of ``window_m`` metres; :func:`apply_bias` corrects the raw steps. The map build alternates the two
with the pose-graph solve a few times (:func:`solve_with_calibration`). A drive with nothing to correct
it (no grounding, no closure) is left as it is.

Poses are [x_m, y_m, yaw_rad]; steps [dx_m, dy_m, dtheta_rad] in the earlier frame.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from driftmap.core.graph import alignment, posegraph
from driftmap.core.graph.constraints import (
    GroundingConstraint,
    LoopConstraint,
    OdometryChain,
    PoseGraphParams,
    PoseGraphResult,
)
from driftmap.core.types import F64
from driftmap.errors import BadInputError

__all__ = ["NO_BIAS", "OdometryBias", "apply_bias", "estimate_bias", "solve_with_calibration"]


@dataclass(frozen=True)
class OdometryBias:
    """One drive's systematic odometry error.

    True translation = ``scale`` x measured translation; true heading change = ``turn_gain`` x measured
    heading change - ``yaw_rate_rad_per_m`` x measured forward travel.
    """

    scale: float  # optimised / measured travel
    yaw_rate_rad_per_m: float  # spurious heading change per metre of forward travel
    turn_gain: float = 1.0  # optimised / measured turning


NO_BIAS = OdometryBias(1.0, 0.0, 1.0)
LOOSE_ODOMETRY_GAIN = 4.0  # odometry noise multiplier of the solves that the calibration is fitted to
TURN_PRIOR_RAD = 0.5  # the turn gain's pull towards 1 weighs as much as this much turning, radians
MAX_SCALE_ERROR = 0.1  # fitted scales are clipped to 1 +- this
MAX_RATE = 0.05  # fitted heading rates are clipped to +- this, radians per metre
MAX_TURN_ERROR = 0.2  # fitted turn gains are clipped to 1 +- this
MAX_STEP_GAIN = 4.0  # an accelerated calibration round moves at most this many times the plain fit's step


def _check(iTj: F64, wTi: F64) -> None:
    if iTj.ndim != 2 or iTj.shape[1] != 3:
        raise BadInputError(f"iTj must be (N-1, 3), got {iTj.shape}", field="iTj")
    if wTi.shape != (iTj.shape[0] + 1, 3):
        raise BadInputError(f"wTi must be ({iTj.shape[0] + 1}, 3), got {wTi.shape}", field="wTi")


def _windows(forward_m: F64, window_m: float) -> list[tuple[int, int]]:
    """Consecutive step ranges [a, b) each covering about ``window_m`` metres of travel."""
    travel = np.cumsum(np.abs(forward_m))
    edges = np.searchsorted(travel, np.arange(window_m, travel[-1] if travel.size else 0.0, window_m))
    bounds = np.unique(np.concatenate([[0], edges + 1, [forward_m.size]]))
    return [(int(a), int(b)) for a, b in itertools.pairwise(bounds) if b > a]


def _bounded(scale: float, rate: float, turn_gain: float) -> OdometryBias:
    return OdometryBias(
        float(np.clip(scale, 1.0 - MAX_SCALE_ERROR, 1.0 + MAX_SCALE_ERROR)),
        float(np.clip(rate, -MAX_RATE, MAX_RATE)),
        float(np.clip(turn_gain, 1.0 - MAX_TURN_ERROR, 1.0 + MAX_TURN_ERROR)),
    )


def estimate_bias(iTj: F64, wTi: F64, window_m: float = 15.0) -> OdometryBias:
    """Fit a drive's odometry scale, heading rate and turn gain to its optimised trajectory.

    Over each window of about ``window_m`` metres, the optimised heading change against the odometry's
    heading change and signed forward travel gives the turn gain and the heading rate (linear least
    squares; a prior worth ``TURN_PRIOR_RAD`` of turning holds the gain at 1 on a drive that barely
    turns); the optimised over the measured straight-line displacement of the windows gives the scale.
    Each is clipped to its ``MAX_*`` bound.

    Args:
        iTj: (N-1, 3) raw odometry steps.
        wTi: (N, 3) optimised poses of the same frames, survey frame.
        window_m: window length, metres of travel.

    Returns:
        The fitted :class:`OdometryBias`; :data:`NO_BIAS` when the drive barely moves.
    """
    iTj, wTi = np.asarray(iTj, dtype=np.float64), np.asarray(wTi, dtype=np.float64)
    _check(iTj, wTi)
    windows = _windows(iTj[:, 0], window_m)
    x = np.array([np.sum(iTj[a:b, 0]) for a, b in windows])
    if x.size == 0 or float(np.sum(x * x)) < window_m**2:
        return NO_BIAS
    turned = np.array([np.sum(iTj[a:b, 2]) for a, b in windows])
    # The optimised turn of each window, unwrapped next to the odometry's (a window may turn past 180 deg).
    optimised = turned + alignment.wrap_angle(np.array([wTi[b, 2] - wTi[a, 2] for a, b in windows]) - turned)
    design = np.vstack([np.column_stack([turned, -x]), [TURN_PRIOR_RAD, 0.0]])
    (turn_gain, rate), *_ = np.linalg.lstsq(design, np.r_[optimised, TURN_PRIOR_RAD], rcond=None)
    # The scale compares straight-line displacements (chords, whatever the start heading), so the odometry's
    # turns are corrected first.
    reckoned = alignment.dead_reckon(apply_bias(iTj, OdometryBias(1.0, float(rate), float(turn_gain))))
    length_odo = np.array([np.hypot(*(reckoned[b, :2] - reckoned[a, :2])) for a, b in windows])
    length_opt = np.array([np.hypot(*(wTi[b, :2] - wTi[a, :2])) for a, b in windows])
    moved = length_odo > 0.5 * window_m
    scale = float(np.sum(length_opt[moved]) / np.sum(length_odo[moved])) if moved.any() else 1.0
    return _bounded(scale, float(rate), float(turn_gain))


def apply_bias(iTj: F64, bias: OdometryBias) -> F64:
    """(N-1, 3) steps corrected for ``bias``: translations scaled, turns scaled, heading rate removed."""
    iTj = np.asarray(iTj, dtype=np.float64)
    out = iTj.copy()
    out[:, :2] *= bias.scale
    out[:, 2] = bias.turn_gain * iTj[:, 2] - bias.yaw_rate_rad_per_m * iTj[:, 0]
    return out


def solve_with_calibration(
    graph: PoseGraphResult,
    chains: Sequence[OdometryChain],
    closures: Sequence[LoopConstraint],
    groundings: Sequence[GroundingConstraint],
    graph_params: PoseGraphParams,
    rounds: int,
    window_m: float,
) -> tuple[PoseGraphResult, list[OdometryBias]]:
    """Alternate odometry self-calibration and the pose-graph solve ``rounds`` times after a first solve.

    Only drives the solution can correct are calibrated: those with two groundings or more, or with an
    accepted loop closure. Each round solves the graph of the latest corrected steps with the odometry
    noise ``LOOSE_ODOMETRY_GAIN`` times larger, so the solution follows the groundings and closures
    rather than the biased odometry, and fits every such drive's bias to it from its raw steps
    (:func:`estimate_bias`). The loose solve still goes only part of the way from the odometry to the
    constraints, so the plain fit closes only part of the gap each round (about half on the simulated
    sites); from the second round on, the step is extrapolated (:func:`_accelerated`). The last solve
    uses the corrected steps with their own noise. Each loose solve starts from the previous solve's poses (a
    warm start: the placement and gauge anchors stay the cold start's); the last one starts cold from the
    placement of the corrected steps (on the 20 km site a last solve started from the last loose round's
    poses settled in a worse minimum: twelve times the final error, 1,000 more closures turned down, 0.5 m
    worse on average), solved by ``graph_params.last_solver``: from the placement Levenberg-Marquardt can
    crawl for hundreds of iterations, or stop on a slow stretch, short of the minimum the dog leg reaches.

    Args:
        graph: the first solution of the graph of ``chains``, ``closures`` and ``groundings``.
        chains, closures, groundings, graph_params: that graph, as given to
            :func:`driftmap.core.graph.posegraph.optimise_pose_graph`.
        rounds: at most this many calibration passes; fewer when the fit settles (0: ``graph`` as it is).
        window_m: travel per fitting window, metres.

    Returns:
        The last solution and each chain's fitted bias (:data:`NO_BIAS` for drives left alone).
    """
    accepted = [c for c, ok in zip(closures, graph.closure_accepted, strict=True) if ok]
    touched = {c.a[0] for c in accepted} | {c.b[0] for c in accepted}
    grounded = [sum(g.frame[0] == k for g in groundings) for k in range(len(chains))]
    informed = [k in touched or grounded[k] >= 2 for k in range(len(chains))]
    biases = [NO_BIAS] * len(chains)
    if not any(informed) or rounds <= 0:
        return graph, biases
    history: list[tuple[F64, F64] | None] = [None] * len(chains)
    fixed = list(chains)
    start: Sequence[F64 | None] = list(graph.wTi)  # each loose solve starts from the previous solution
    for _ in range(rounds):
        loose = [_loosened(chain, LOOSE_ODOMETRY_GAIN) for chain in fixed]
        fitted = posegraph.optimise_pose_graph(loose, closures, groundings, graph_params, start)
        start = list(fitted.wTi)
        previous = biases
        biases = []
        for k, (chain, wTi, ok) in enumerate(zip(chains, fitted.wTi, informed, strict=True)):
            if not ok:
                biases.append(NO_BIAS)
                continue
            current, fit = _as_vector(previous[k]), _as_vector(estimate_bias(chain.iTj, wTi, window_m))
            biases.append(_from_vector(_accelerated(current, fit, history[k])))
            history[k] = (current, fit)
        fixed = [_corrected(chain, bias) for chain, bias in zip(chains, biases, strict=True)]
        if all(_settled(a, b) for a, b in zip(previous, biases, strict=True)):
            break
    last = replace(graph_params, solver=graph_params.last_solver)
    return posegraph.optimise_pose_graph(fixed, closures, groundings, last), biases


def _as_vector(bias: OdometryBias) -> F64:
    """(3,) [log scale, heading rate rad/m, log turn gain]: the coordinates the rounds extrapolate in."""
    return np.array([np.log(bias.scale), bias.yaw_rate_rad_per_m, np.log(bias.turn_gain)])


def _from_vector(v: F64) -> OdometryBias:
    return _bounded(float(np.exp(v[0])), float(v[1]), float(np.exp(v[2])))


def _accelerated(current: F64, fit: F64, history: tuple[F64, F64] | None) -> F64:
    """The next estimate of the fixed point ``x = fit(x)`` of the calibration rounds, (3,) like ``current``.

    A plain round takes ``fit``. When the loose solve closes a fraction f of the gap, fit(x) moves by
    (1 - f) per unit of x; the last two rounds measure that slope per coordinate (a secant), and the step
    ``fit - current`` is divided by f, at most ``MAX_STEP_GAIN`` times over (a slope outside [0, 1) from
    noise falls back to the plain step or that cap).
    """
    if history is None:
        return fit
    before, fit_before = history
    moved = current - before
    slope = np.divide(fit - fit_before, moved, out=np.zeros(3), where=np.abs(moved) > 1e-9)
    slope = np.clip(slope, 0.0, 1.0 - 1.0 / MAX_STEP_GAIN)
    return current + (fit - current) / (1.0 - slope)


def _settled(a: OdometryBias, b: OdometryBias) -> bool:
    """Whether two successive fits agree to 0.1 % in scale and turn gain, 0.01 degree per 100 m in rate."""
    return (
        abs(a.scale - b.scale) < 1e-3
        and abs(a.turn_gain - b.turn_gain) < 1e-3
        and abs(a.yaw_rate_rad_per_m - b.yaw_rate_rad_per_m) < 2e-6
    )


def _corrected(chain: OdometryChain, bias: OdometryBias) -> OdometryChain:
    steps = apply_bias(chain.iTj, bias)
    start = None if chain.wTi_init is None else alignment.dead_reckon(steps, chain.wTi_init[0])
    return replace(chain, iTj=steps, wTi_init=start)


def _loosened(chain: OdometryChain, gain: float) -> OdometryChain:
    """The chain with its odometry noise ``gain`` times larger (information ``gain``^2 times smaller)."""
    information = None if chain.information is None else chain.information / gain**2
    return replace(chain, sigmas=np.asarray(chain.sigmas) * gain, information=information)
