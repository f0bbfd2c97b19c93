"""Self-calibration of each drive's odometry from the optimised map (beyond the paper).

Ground-plane odometry inherits two systematic errors from its camera calibration, and neither averages
out along a drive:

* **Scale.** A camera height or pitch off by a percent makes every step a percent too long or short.
* **Heading rate.** A camera looking a fraction of a degree off the vehicle axis sees the floor slide
  sideways as the vehicle drives straight; the odometry reads the slide as turning, so the heading drifts
  by a fixed angle per metre of forward travel (opposite when reversing).

Groundings and loop closures reveal both: after an optimisation, the optimised trajectory turns and
stretches less or more than the odometry said, consistently. :func:`estimate_bias` fits one scale and one
heading rate per drive by comparing the raw odometry with the optimised poses over windows of
``window_m`` metres; :func:`apply_bias` corrects the raw steps. The map build alternates the two with the
pose-graph solve a few times (:func:`solve_with_calibration`). A drive with nothing to correct it
(no grounding, no closure) is left as it is.

Poses are [x_m, y_m, yaw_rad]; steps [dx_m, dy_m, dtheta_rad] in the earlier frame.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from driftmap.core import alignment, posegraph
from driftmap.errors import BadInputError

__all__ = ["NO_BIAS", "OdometryBias", "apply_bias", "estimate_bias", "solve_with_calibration"]

F64 = NDArray[np.float64]


@dataclass(frozen=True)
class OdometryBias:
    """One drive's systematic odometry error: true step = scale * measured translation, heading minus rate."""

    scale: float  # optimised / measured travel
    yaw_rate_rad_per_m: float  # spurious heading change per metre of forward travel


NO_BIAS = OdometryBias(1.0, 0.0)
LOOSE_ODOMETRY_GAIN = 4.0  # odometry noise multiplier of the solves that the calibration is fitted to


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


def estimate_bias(
    iTj: F64, wTi: F64, window_m: float = 15.0, max_scale_error: float = 0.1, max_rate: float = 0.05
) -> OdometryBias:
    """Fit a drive's odometry scale and heading rate to its optimised trajectory.

    Over each window of about ``window_m`` metres the odometry's heading change minus the optimised one,
    against the window's signed forward travel, gives the heading rate (least squares through zero); the
    optimised over the measured straight-line displacement of the windows gives the scale.

    Args:
        iTj: (N-1, 3) raw odometry steps.
        wTi: (N, 3) optimised poses of the same frames, survey frame.
        window_m: window length, metres of travel.
        max_scale_error: the scale is clipped to 1 +- this.
        max_rate: the heading rate is clipped to +- this, radians per metre.

    Returns:
        The fitted :class:`OdometryBias`; :data:`NO_BIAS` when the drive barely moves.
    """
    iTj, wTi = np.asarray(iTj, dtype=np.float64), np.asarray(wTi, dtype=np.float64)
    _check(iTj, wTi)
    windows = _windows(iTj[:, 0], window_m)
    forward, dtheta_odo, dtheta_opt, length_odo, length_opt = [], [], [], [], []
    for a, b in windows:
        steps = iTj[a:b]
        heading = np.concatenate([[0.0], np.cumsum(steps[:-1, 2])])
        c, s = np.cos(heading), np.sin(heading)
        disp_odo = np.array(
            [np.sum(c * steps[:, 0] - s * steps[:, 1]), np.sum(s * steps[:, 0] + c * steps[:, 1])]
        )
        forward.append(float(np.sum(steps[:, 0])))
        dtheta_odo.append(float(np.sum(steps[:, 2])))
        turn = wTi[b, 2] - wTi[a, 2]
        dtheta_opt.append(float(np.arctan2(np.sin(turn), np.cos(turn))))
        length_odo.append(float(np.hypot(*disp_odo)))
        length_opt.append(float(np.hypot(*(wTi[b, :2] - wTi[a, :2]))))
    x = np.asarray(forward)
    if x.size == 0 or float(np.sum(x * x)) < window_m**2:
        return NO_BIAS
    excess = np.asarray(dtheta_odo) - np.asarray(dtheta_opt)
    excess = np.arctan2(np.sin(excess), np.cos(excess))
    rate = float(np.sum(excess * x) / np.sum(x * x))
    moved = np.asarray(length_odo) > 0.5 * window_m
    scale = (
        float(np.sum(np.asarray(length_opt)[moved]) / np.sum(np.asarray(length_odo)[moved]))
        if moved.any()
        else 1.0
    )
    return OdometryBias(
        float(np.clip(scale, 1.0 - max_scale_error, 1.0 + max_scale_error)),
        float(np.clip(rate, -max_rate, max_rate)),
    )


def apply_bias(iTj: F64, bias: OdometryBias) -> F64:
    """(N-1, 3) steps corrected for ``bias``: translations scaled, heading rate removed per forward metre."""
    iTj = np.asarray(iTj, dtype=np.float64)
    out = iTj.copy()
    out[:, :2] *= bias.scale
    out[:, 2] -= bias.yaw_rate_rad_per_m * iTj[:, 0]
    return out


def solve_with_calibration(
    graph: posegraph.PoseGraphResult,
    chains: Sequence[posegraph.OdometryChain],
    closures: Sequence[posegraph.LoopClosure],
    groundings: Sequence[posegraph.Grounding],
    graph_params: posegraph.PoseGraphParams,
    rounds: int,
    window_m: float,
) -> tuple[posegraph.PoseGraphResult, list[OdometryBias]]:
    """Alternate odometry self-calibration and the pose-graph solve ``rounds`` times after a first solve.

    Only drives the solution can correct are calibrated: those with two groundings or more, or with an
    accepted loop closure. Each round solves the graph of the latest corrected steps with the odometry
    noise ``LOOSE_ODOMETRY_GAIN`` times larger, so the solution follows the groundings and closures
    rather than the biased odometry, and fits every such drive's bias to it from its raw steps
    (:func:`estimate_bias`). The last solve uses the corrected steps with their own noise.

    Args:
        graph: the first solution of the graph of ``chains``, ``closures`` and ``groundings``.
        chains, closures, groundings, graph_params: that graph, as given to
            :func:`driftmap.core.posegraph.optimise_pose_graph`.
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
    fixed = list(chains)
    for _ in range(rounds):
        loose = [_loosened(chain, LOOSE_ODOMETRY_GAIN) for chain in fixed]
        fitted = posegraph.optimise_pose_graph(loose, closures, groundings, graph_params)
        previous, biases = (
            biases,
            [
                estimate_bias(chain.iTj, wTi, window_m) if ok else NO_BIAS
                for chain, wTi, ok in zip(chains, fitted.wTi, informed, strict=True)
            ],
        )
        fixed = [_corrected(chain, bias) for chain, bias in zip(chains, biases, strict=True)]
        if all(_settled(a, b) for a, b in zip(previous, biases, strict=True)):
            break
    return posegraph.optimise_pose_graph(fixed, closures, groundings, graph_params), biases


def _settled(a: OdometryBias, b: OdometryBias) -> bool:
    """Whether two successive fits agree to 0.1 % in scale and 0.01 degree per 100 m in heading rate."""
    return abs(a.scale - b.scale) < 1e-3 and abs(a.yaw_rate_rad_per_m - b.yaw_rate_rad_per_m) < 2e-6


def _corrected(chain: posegraph.OdometryChain, bias: OdometryBias) -> posegraph.OdometryChain:
    steps = apply_bias(chain.iTj, bias)
    start = None if chain.wTi_init is None else alignment.dead_reckon(steps, chain.wTi_init[0])
    return replace(chain, iTj=steps, wTi_init=start)


def _loosened(chain: posegraph.OdometryChain, gain: float) -> posegraph.OdometryChain:
    """The chain with its odometry noise ``gain`` times larger (information ``gain``^2 times smaller)."""
    information = None if chain.information is None else chain.information / gain**2
    return replace(chain, sigmas=np.asarray(chain.sigmas) * gain, information=information)
