"""Slowly varying camera pitch (horizon) of the bird's-eye odometry (beyond the paper).

The horizon self-calibration (:mod:`driftmap.core.odometry`) estimates, for every moving step, the horizon
offset ``delta`` (pixels, ``H_true(u, v) = H(u, v + delta)``) that keeps the distance between the matched
floor points of the nearest and the farthest ROI slice the same in both frames (floor motion is rigid), and
applies the drive's median to every step. That is right for a camera whose pitch to the floor is off by a
fixed amount; it is wrong where the pitch to the floor ahead changes along the drive: a vehicle entering or
leaving a ramp (the floor ahead bends up or down under it), a load that settles, a suspension that sags on a
slope. There the bird's-eye scale drifts with the pitch: on KITTI clip 2 (a ramp) the per-step estimates
fall from ~30 px to ~5 px over 50 m, and one median for the drive read the first steps 25-36 % long and the
last ~10 % short.

:func:`track_horizon` turns the noisy per-step estimates into a pitch track that only departs from the drive's
median where the evidence says so:

* **Smoothing.** A local robust mean at each step: Gaussian weights in distance travelled (``window_m``, the
  standard deviation; a road's or a ramp's vertical curve spans tens of metres, while ride bounce at 1-3 Hz
  averages out over it), with Huber weights (``HUBER_K`` robust standard deviations) so a bad step's estimate
  (a false match, a sign flip of the rigid-gap equation) does not pull it. The robust standard deviation of
  one estimate is the MAD of the residuals about the track, so a trend does not inflate it.
* **Gate.** The local mean replaces the median only where it differs from it by more than ``gate_z`` of its
  own standard error (``sigma * sqrt(sum w^2) / sum w``) and enough estimates support it (``MIN_EFFECTIVE``
  effective samples): a drive at one pitch keeps the median, since chance departures of its local means stay
  within the gate, which also holds the simulated mine vehicles (ride bounce of about a degree at 1-3 Hz,
  a fixed calibration error per drive).

Camera height (the overall scale) is not observable from the floor this way, only the pitch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["HorizonTrack", "horizon_floor", "track_horizon"]

HUBER_K = 2.0  # Huber threshold of the local robust mean, robust standard deviations
IRLS_ITERATIONS = 5  # reweighting rounds of each local mean
MIN_ESTIMATES = 3  # fewer finite estimates than this: no horizon at all
MIN_EFFECTIVE = 8.0  # fewer effective estimates than this in a step's window: it keeps the median
WINDOW_SPAN = 3.0  # estimates farther than this many window_m from a step do not enter its mean
GRID_STEP = 0.25  # the local means are computed every this many window_m along the drive, then interpolated


@dataclass(frozen=True)
class HorizonTrack:
    """Per-step horizon offsets of a drive.

    Attributes:
        median_px: the drive's median horizon offset, pixels.
        offsets_px: ``(N,)`` float64 offset applied to each step, pixels: the local mean where it passed the
            gate, else the median.
        local_px: ``(N,)`` float64 local robust mean at each step (NaN where no estimate is near), pixels.
        se_px: ``(N,)`` float64 standard error of ``local_px``, pixels (inf where undetermined).
        sigma_px: robust standard deviation of one step's estimate about the track, pixels.
    """

    median_px: float
    offsets_px: NDArray[np.float64]
    local_px: NDArray[np.float64]
    se_px: NDArray[np.float64]
    sigma_px: float

    @property
    def tracked(self) -> NDArray[np.bool_]:
        """``(N,)`` bool: the step's offset is its local mean, not the drive's median."""
        return np.asarray(self.offsets_px != self.median_px)


def _local_means(
    estimates: NDArray[np.float64], at_m: NDArray[np.float64], window_m: float, scale: float
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Gaussian-windowed Huber means of the finite ``estimates`` (positions ``at_m``) at every position.

    The means are computed every ``GRID_STEP * window_m`` metres along the drive and interpolated (a mean
    over a Gaussian window barely changes within a quarter of it), so the cost does not grow with the
    frame rate. Returns ``(mean, sum_w, sum_w2)`` per position; ``mean`` is NaN where no estimate is near.
    """
    ok = np.isfinite(estimates)
    pos, vals = at_m[ok], estimates[ok]  # sorted: travel only grows
    spacing = max(GRID_STEP * window_m, float(at_m[-1] - at_m[0]) / len(at_m))  # at most ~N + 1 means
    grid = np.arange(float(at_m[0]), float(at_m[-1]) + spacing, spacing)
    n = len(grid)
    mean, sum_w, sum_w2 = np.full(n, math.nan), np.zeros(n), np.zeros(n)
    lo = np.searchsorted(pos, grid - WINDOW_SPAN * window_m, side="left")
    hi = np.searchsorted(pos, grid + WINDOW_SPAN * window_m, side="right")
    cut = HUBER_K * scale
    for k in range(n):
        v = vals[lo[k] : hi[k]]
        if len(v) == 0:
            continue
        w0 = np.exp(-0.5 * ((pos[lo[k] : hi[k]] - grid[k]) / window_m) ** 2)
        mu, w = float(np.median(v)), w0
        for _ in range(IRLS_ITERATIONS):
            r = np.abs(v - mu)
            w = w0 * (np.minimum(1.0, cut / np.maximum(r, 1e-12)) if cut > 0 else 1.0)
            mu = float(np.sum(w * v) / np.sum(w))
        mean[k], sum_w[k], sum_w2[k] = mu, float(np.sum(w)), float(np.sum(w * w))
    known = np.isfinite(mean)
    if not known.any():
        return np.full(len(at_m), math.nan), np.zeros(len(at_m)), np.zeros(len(at_m))
    at_mean = np.interp(at_m, grid[known], mean[known])
    at_mean[np.interp(at_m, grid, (~known).astype(np.float64)) > 0] = math.nan  # next to a gap: no mean
    return at_mean, np.interp(at_m, grid, sum_w), np.interp(at_m, grid, sum_w2)


def track_horizon(
    estimates_px: NDArray[np.float64], travel_m: NDArray[np.float64], window_m: float, gate_z: float
) -> HorizonTrack | None:
    """A drive's per-step horizon offsets from its per-step estimates (see the module docstring).

    Args:
        estimates_px: ``(N,)`` float64 horizon offset estimated from each step, pixels; NaN where the step
            gave none (stationary, low confidence, no root).
        travel_m: ``(N,)`` float64 non-negative distance travelled in each step, metres (any consistent
            estimate: it only places the steps along the drive).
        window_m: standard deviation of the Gaussian window in distance travelled, metres; ``<= 0`` keeps
            the median for every step.
        gate_z: a local mean is applied where it departs from the median by more than this many of its
            standard errors.

    Returns:
        The :class:`HorizonTrack`, or None when fewer than ``MIN_ESTIMATES`` estimates are finite.

    Raises:
        ValueError: shapes differ, or a travel is negative or not finite.
    """
    est = np.asarray(estimates_px, dtype=np.float64)
    travel = np.asarray(travel_m, dtype=np.float64)
    if est.ndim != 1 or travel.shape != est.shape:
        raise ValueError(f"estimates_px and travel_m must be (N,), got {est.shape} and {travel.shape}")
    if not np.all(np.isfinite(travel)) or np.any(travel < 0):
        raise ValueError("travel_m must be finite and >= 0")
    ok = np.isfinite(est)
    if int(ok.sum()) < MIN_ESTIMATES:
        return None
    median = float(np.median(est[ok]))
    n = len(est)
    flat = np.full(n, median)
    mad = 1.4826 * float(np.median(np.abs(est[ok] - median)))
    if window_m <= 0:
        return HorizonTrack(median, flat, flat.copy(), np.full(n, math.inf), mad)
    at = np.cumsum(travel) - 0.5 * travel  # the middle of each step along the drive
    local, _, _ = _local_means(est, at, window_m, mad)
    resid = est[ok] - local[ok]  # scatter about the track, not about the median: a trend does not count
    sigma = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
    local, sum_w, sum_w2 = _local_means(est, at, window_m, sigma)
    with np.errstate(divide="ignore", invalid="ignore"):
        n_eff = np.where(sum_w2 > 0, sum_w**2 / sum_w2, 0.0)
        se = np.where(sum_w > 0, sigma * np.sqrt(sum_w2) / sum_w, math.inf)
    apply = np.isfinite(local) & (n_eff >= MIN_EFFECTIVE) & (np.abs(local - median) > gate_z * se)
    return HorizonTrack(median, np.where(apply, local, median), local, se, sigma)


FloorPair = tuple[NDArray[np.float64], NDArray[np.float64]]  # a match's floor points (previous, current)


def _to_floor(hom: NDArray[np.float64], pts: NDArray[np.float64]) -> NDArray[np.float64]:
    h = np.asarray(pts, dtype=np.float64) @ hom[:, :2].T + hom[:, 2]
    return np.asarray(h[..., :2] / h[..., 2:3])


def _shifted(hom: NDArray[np.float64], offset_px: float) -> NDArray[np.float64]:
    """``H'(u, v) = H(u, v + offset_px)``."""
    return np.asarray(hom @ np.array([[1.0, 0.0, 0.0], [0.0, 1.0, offset_px], [0.0, 0.0, 1.0]]))


def horizon_floor(
    hom: NDArray[np.float64],
    pairs: list[list[tuple[NDArray[np.float64], NDArray[np.float64]]]],
    estimates_px: NDArray[np.float64],
    window_m: float,
    gate_z: float,
) -> tuple[HorizonTrack, list[list[FloorPair]]] | None:
    """Track the horizon of a drive and map every step's matched pixels to the floor with its own offset.

    Args:
        hom: ``(3, 3)`` the drive's pixel -> floor (x forward, y left, metres) ground homography.
        pairs: per step, its matched pixel pairs ``(previous (2,), current (2,))``, the ROI-centre match
            first (empty for a step without matches).
        estimates_px: ``(N,)`` float64 per-step horizon offset estimates, NaN where none.
        window_m, gate_z: see :func:`track_horizon`.

    Returns:
        ``(track, floor)``: the :class:`HorizonTrack` and, per step, its pairs as floor points through
        ``H(u, v + offset)``; None when fewer than ``MIN_ESTIMATES`` estimates are finite.
    """
    est = np.asarray(estimates_px, dtype=np.float64)
    if len(pairs) != len(est):
        raise ValueError(f"{len(pairs)} steps of pairs but {len(est)} estimates")
    ok = np.isfinite(est)
    if int(ok.sum()) < MIN_ESTIMATES:
        return None
    at_median = _shifted(np.asarray(hom, dtype=np.float64), float(np.median(est[ok])))
    travel = np.zeros(len(est))
    for k, p in enumerate(pairs):
        if p:
            f1, f2 = _to_floor(at_median, p[0][0]), _to_floor(at_median, p[0][1])
            travel[k] = float(np.hypot(*(f1 - f2)))
    track = track_horizon(est, travel, window_m, gate_z)
    assert track is not None  # as many finite estimates as checked above
    homs: dict[float, NDArray[np.float64]] = {}
    floor: list[list[FloorPair]] = []
    for off, p in zip(track.offsets_px.tolist(), pairs, strict=True):
        h = homs.setdefault(off, _shifted(np.asarray(hom, dtype=np.float64), off))
        floor.append([(_to_floor(h, a), _to_floor(h, b)) for a, b in p])
    return track, floor
