"""What :class:`driftmap.core.localisation.localiser.Localiser` reports per frame (:class:`Estimate`) and keeps between
frames (:class:`LocaliserState`, small enough for the live server's shared store)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from driftmap.core.localisation.track import TrackState
from driftmap.core.localisation.turns import TurnHistory
from driftmap.core.types import F64
from driftmap.errors import BadInputError

__all__ = ["Estimate", "LocaliserState"]


@dataclass(frozen=True)
class Estimate:
    """The position estimate of one frame.

    Attributes:
        node: b(i), the best node (eq. 11).
        x_m: the vehicle's position, survey frame x (east), metres: the continuous track along the mapped
            tunnels (:mod:`driftmap.core.localisation.track`), b(i)'s centre before the track has one.
        y_m: ... y (north), metres.
        score: the paper's X_i(b(i)) in [0, 1] (eq. 11); single-image mode: 1 - d_best / median d over the map.
            Kept for [SSLAM]'s protocol; the product reports :attr:`confidence`.
        matched: ``confidence >= HmmParams.confidence_threshold`` and the frame is not lost.
        lost: the filter is lost: this frame and the ones before it failed the lost test, at least
            ``lost_report_frames`` counted in a row (it re-initialises after ``lost_frames``).
        evaluated_nodes: number of nodes compared with the query this frame.
        ms: wall time of the step (odometry included), milliseconds.
        distinct: how much better the track's frames match their b than anywhere else: this frame's
            ``1 - d(i, b(i)) / d_other`` clipped to [0, 1], with d_other the least d of the compared far nodes
            (the lost test's; the median d of the compared nodes when it is lower or no far node was
            compared), averaged exponentially (weight ``HmmParams.distinct_memory``, starting from 0) over
            the frames since b last jumped further than two frame reaches or the belief started globally
            (single-image mode: ``score``).
        confidence: the probability that the position is right (within the evaluation tolerance), in [0, 1]:
            the calibration of ``score x distinct`` (``HmmParams.calibration``); 0 when lost. The one
            confidence the CSV, the live API and the UI report.
        yaw_rad: heading, survey frame, radians counter-clockwise from +x (east); NaN while unknown.
        speed_mps: signed speed from odometry (negative: reversing), m/s; NaN without odometry.
        moving: the vehicle moves (odometry faster than ``TrackParams.moving_mps``; without odometry: the
            view changed since the last frame).
        odometry: this frame's motion came from the camera's ground-plane odometry (a usable step); False:
            appearance alone (no camera, an unusable step, a dropped frame).
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
    confidence: float = 0.0
    yaw_rad: float = float("nan")
    speed_mps: float = float("nan")
    moving: bool = False
    odometry: bool = False

    @property
    def raw_confidence(self) -> float:
        """``score x distinct`` in [0, 1] before calibration: the belief is on b(i) *and* the track's views
        look like it (a view that matches another part of the mine as well is ambiguous however well it
        matches b(i))."""
        return self.score * self.distinct


def _no_query() -> NDArray[np.float32]:
    return np.zeros((0, 0), dtype=np.float32)


def _no_frame() -> NDArray[np.uint8]:
    return np.zeros((0, 0), dtype=np.uint8)


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
        track: the continuous position track (:class:`~driftmap.core.localisation.track.TrackState`).
        last_frame: (H, W) uint8 last raw frame, for the next odometry step; (0, 0) without odometry.
        turns: the driven path's heading for the turn check (:mod:`driftmap.core.localisation.turns`).
    """

    belief: F64
    last_t_s: float
    lost_count: int
    steps: int
    moving: int = 0
    last_query: NDArray[np.float32] = field(default_factory=_no_query)
    node: int = -1
    distinct: float = 0.0
    track: TrackState = field(default_factory=TrackState.empty)
    last_frame: NDArray[np.uint8] = field(default_factory=_no_frame)
    turns: TurnHistory = field(default_factory=TurnHistory.empty)

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
            "track": self.track.to_arrays(),
            "last_frame": np.asarray(self.last_frame, dtype=np.uint8),
            "turns": self.turns.to_arrays(),
        }

    @classmethod
    def from_arrays(cls, arrays: dict[str, NDArray[np.generic]]) -> LocaliserState:
        """Rebuild a state from :meth:`to_arrays` output (a state stored before a field existed starts that
        field afresh)."""
        try:
            return cls(
                belief=np.array(arrays["belief"], dtype=np.float64),
                last_t_s=float(arrays["last_t_s"]),
                lost_count=int(arrays["lost_count"]),
                steps=int(arrays["steps"]),
                moving=int(arrays.get("moving", 0)),
                last_query=np.array(arrays.get("last_query", _no_query()), dtype=np.float32),
                node=int(arrays.get("node", -1)),
                distinct=float(arrays.get("distinct", 0.0)),
                track=TrackState.from_arrays(np.asarray(arrays.get("track", np.zeros(0)), dtype=np.float64)),
                last_frame=np.array(arrays.get("last_frame", _no_frame()), dtype=np.uint8),
                turns=TurnHistory.from_arrays(np.asarray(arrays.get("turns", np.zeros(0)), dtype=np.float64)),
            )
        except KeyError as exc:
            raise BadInputError("stored localiser state is missing an array", field=str(exc.args[0])) from exc
