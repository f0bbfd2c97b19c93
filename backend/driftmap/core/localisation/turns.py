"""Turns driven against the map's turns: odometry's heading change checked along the topological graph.

Beyond [SSLAM]: its transition (eq. 9-10) lets the belief move anywhere within a reach, and the odometry-gated
transition (:mod:`driftmap.core.localisation.localiser`) by the distance driven. Neither asks *which way* the vehicle went.
A look-alike place in another tunnel can follow the distance driven, but rarely the turns: a vehicle that has
just rounded a 90-degree corner is not in the middle of a long straight drive.

The check compares two heading changes over the last ``window_m`` metres of path:

* **driven** (:class:`TurnHistory`): the sum of the usable odometry steps' ``dtheta_rad`` (eq. 1-2) since
  the vehicle was ``window_m`` metres of travel back. Sampled every ``sample_m`` metres of travel; forgotten
  when a step is unusable (the heading change of that frame is unknown) or the direction of travel reverses
  (the path behind is then not the path driven).
* **mapped** (:func:`map_turns`): for each node j, the heading change |h_last - h_first| along every path of
  mapped edges (segments between directly driven node centres) that starts at j and is ``window_m`` +- one
  ``tolerance_m`` long. Magnitudes only: the same corner turns left one way and right the other, and a
  reversing vehicle's body turns as its path does.

Each time the driven window advances by ``sample_m``, the prior is multiplied by

    f_j = floor + (1 - floor) * exp(-0.5 * (min_k |turn_driven - turn_jk| / sigma)^2),
    sigma = sigma_rad + sigma_frac * turn_driven,

a node with no mapped path that long (a dead end, a gap in the mapped edges) gets f_j = 1 (no evidence).
``floor`` bounds what one check can take from the right node when the map's centre-line turns and the driven
turns disagree (corners cut between node centres, the window's ends half a node off).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from driftmap.core.topomap.model import wrap_rad
from driftmap.core.types import F64, I64
from driftmap.errors import BadInputError

__all__ = ["TURNS_DEFAULT", "TurnHistory", "TurnParams", "map_turns", "turn_likelihood"]

_MAX_PATHS = 24  # mapped turns kept per node (distinct to 0.01 rad)


@dataclass(frozen=True)
class TurnParams:
    """The turn check's window and noise model."""

    window_m: float = 15.0  # heading change compared over this much path, metres
    sample_m: float = 2.5  # the driven heading is sampled (and the check run) every this much travel, metres
    tolerance_m: float = 5.0  # mapped paths within this of window_m count (the window's ends are a node off)
    sigma_rad: float = 0.3  # sd of driven vs mapped turn at no turn (odometry yaw drift, centre-line paths)
    sigma_frac: float = 0.25  # ... plus this share of the driven turn (corners cut between node centres)
    floor: float = (
        0.4  # the likelihood of a node whose mapped turns all disagree, relative to one that agrees
    )

    def __post_init__(self) -> None:
        for name in ("window_m", "sample_m", "tolerance_m", "sigma_rad"):
            if not getattr(self, name) > 0:
                raise BadInputError(f"must be positive, got {getattr(self, name)}", field=name)
        if not self.sigma_frac >= 0.0:
            raise BadInputError(f"must be non-negative, got {self.sigma_frac}", field="sigma_frac")
        if not 0.0 < self.floor <= 1.0:
            raise BadInputError(f"must be in (0, 1], got {self.floor}", field="floor")


TURNS_DEFAULT = TurnParams()


def map_turns(centres_m: F64, edges: I64, params: TurnParams = TURNS_DEFAULT) -> F64:
    """(M, K) float64 each node's mapped heading changes over ``window_m`` +- ``tolerance_m`` of path, radians
    in [0, pi]; NaN-padded (a row of NaN: no mapped path that long from the node).

    Args:
        centres_m: (M, 2) float64 node centres, survey frame, metres.
        edges: (E, 2) int64 directly driven node pairs (undirected).
        params: the window.
    """
    centres = np.asarray(centres_m, dtype=np.float64)
    m = centres.shape[0]
    if centres.ndim != 2 or centres.shape[1] != 2:
        raise BadInputError(f"centres_m must be (M, 2), got {centres.shape}", field="centres_m")
    out = np.full((m, _MAX_PATHS), np.nan)
    edges = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if edges.size == 0:
        return out
    neighbours: list[list[int]] = [[] for _ in range(m)]
    for a, b in edges:
        if a != b:
            neighbours[int(a)].append(int(b))
            neighbours[int(b)].append(int(a))
    lo, hi = params.window_m - params.tolerance_m, params.window_m + params.tolerance_m
    for j in range(m):
        turns: set[float] = set()
        # depth-first over simple paths from j: (node, path length so far, first heading, visited)
        stack: list[tuple[int, float, float, frozenset[int]]] = [(j, 0.0, math.nan, frozenset((j,)))]
        while stack and len(turns) < _MAX_PATHS:
            node, length, first, seen = stack.pop()
            for nxt in neighbours[node]:
                if nxt in seen:
                    continue
                dx, dy = centres[nxt] - centres[node]
                seg = math.hypot(dx, dy)
                if seg <= 0:
                    continue
                heading = math.atan2(dy, dx)
                start = heading if math.isnan(first) else first
                total = length + seg
                if total >= lo:
                    turn = abs(float(wrap_rad(np.asarray(heading - start))))
                    turns.add(round(turn, 2))
                if total < hi:
                    stack.append((nxt, total, start, seen | {nxt}))
        if turns:
            vals = sorted(turns)[:_MAX_PATHS]
            out[j, : len(vals)] = vals
    return out


def turn_likelihood(turn_rad: float, mapped: F64, params: TurnParams = TURNS_DEFAULT) -> F64:
    """(M,) float64 the check's factor f_j (module docstring) for a driven heading change ``turn_rad``.

    Args:
        turn_rad: |driven heading change| over the window, radians.
        mapped: (M, K) :func:`map_turns` of the map.
        params: the noise model.
    """
    sigma = params.sigma_rad + params.sigma_frac * abs(turn_rad)
    with np.errstate(invalid="ignore"):
        miss = np.nanmin(np.abs(mapped - abs(turn_rad)), axis=1, initial=np.inf)
    f = params.floor + (1.0 - params.floor) * np.exp(-0.5 * (miss / sigma) ** 2)
    return np.asarray(np.where(np.isfinite(miss), f, 1.0), dtype=np.float64)


@dataclass(frozen=True)
class TurnHistory:
    """The driven path's heading, sampled by travel, kept between frames.

    Attributes:
        samples: (K, 2) float64 (travel_m, heading_rad) cumulative since the history started, one per
            ``sample_m`` of travel, oldest first, the last at most ``window_m + sample_m`` behind ``now``.
        now: (2,) float64 (travel_m, heading_rad) cumulative at the last frame.
        sign: the direction of travel (+1 forward, -1 reversing, 0 not yet known).
    """

    samples: F64
    now: F64
    sign: float = 0.0

    @classmethod
    def empty(cls) -> TurnHistory:
        return cls(np.zeros((0, 2)), np.zeros(2), 0.0)

    def advance(self, dx_m: float, dtheta_rad: float, params: TurnParams) -> tuple[TurnHistory, float | None]:
        """The history after one usable, non-stationary odometry step, and the driven |turn| over the window
        when this step completed a sample and the history spans the window (else None).

        Args:
            dx_m: the step's signed forward travel, metres.
            dtheta_rad: its heading change, counter-clockwise, radians.
            params: window and sampling.
        """
        sign = float(np.sign(dx_m))
        if sign == 0.0:
            return self, None
        samples, now = self.samples, self.now
        if self.sign != 0.0 and sign != self.sign:  # reversed: a new path starts here
            samples, now = np.zeros((0, 2)), np.zeros(2)
        now = now + np.array([abs(dx_m), dtheta_rad])
        last_s = samples[-1, 0] if samples.shape[0] else -math.inf
        if samples.shape[0] and now[0] - last_s < params.sample_m:
            return TurnHistory(samples, now, sign), None
        samples = np.vstack([samples, now[None, :]]) if samples.size else now[None, :].copy()
        back = now[0] - params.window_m
        older = np.flatnonzero(samples[:, 0] <= back)
        if older.size == 0:
            return TurnHistory(samples, now, sign), None
        samples = samples[older[-1] :]  # keep the newest sample at least a window back
        turn = abs(float(wrap_rad(now[1] - samples[0, 1])))
        return TurnHistory(samples, now, sign), turn

    def to_arrays(self) -> F64:
        """(3 + 2K,) float64 packed for the localiser's stored state."""
        return np.asarray(np.r_[self.sign, self.now, self.samples.ravel()], dtype=np.float64)

    @classmethod
    def from_arrays(cls, packed: F64) -> TurnHistory:
        """Inverse of :meth:`to_arrays` (a malformed array: an empty history)."""
        a = np.asarray(packed, dtype=np.float64).ravel()
        if a.size < 3 or (a.size - 3) % 2:
            return cls.empty()
        return cls(a[3:].reshape(-1, 2).copy(), a[1:3].copy(), float(a[0]))
