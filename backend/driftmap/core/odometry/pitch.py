"""Slowly varying camera pitch (horizon) of the bird's-eye odometry (beyond the paper).

The horizon self-calibration (:mod:`driftmap.core.odometry.drive`) estimates, for every moving step, the horizon
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
  averages out over it), each estimate weighted by its step's travel (its precision: an estimate's variance
  falls as 1 / travel), with Huber weights (``HUBER_K`` robust standard deviations) so a bad step's estimate
  (a false match, a root of the rigid-gap equation far off) does not pull it. The robust standard deviation
  of one estimate is the MAD of the residuals about the track, so a trend does not inflate it.
* **Gate.** A step's offset is its local mean where that departs from the drive's level (the same robust
  mean over the whole drive, so that the estimator's own bias does not pose as a change) by more than
  ``gate_z`` of the local mean's standard error, raised to the family-wise bound of the drive's number of
  independent windows (``FALSE_ALARM``), and where enough estimates support it (``MIN_EFFECTIVE`` effective
  samples); elsewhere the drive's median, as before. A drive at one pitch keeps the median, as the
  simulated mine vehicles do (ride bounce of about a degree at 1-3 Hz, a fixed calibration error per drive:
  on a 12 m window the largest departure on the 3 + 5 mapping drives of the small and medium sites, seed 7,
  is 2.85 standard errors, against gates of 3.2-3.6; 3.37 from the median instead of the level).

Camera height (the overall scale) is not observable from the floor this way, only the pitch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np
from numpy.typing import NDArray

__all__ = ["HorizonTrack", "horizon_floor", "track_horizon"]

HUBER_K = 2.0  # Huber threshold of the local robust mean, robust standard deviations
IRLS_ITERATIONS = 5  # reweighting rounds of each local mean
MIN_ESTIMATES = 3  # fewer finite estimates than this: no horizon at all
MIN_EFFECTIVE = 8.0  # fewer effective estimates than this in a step's window: it keeps the median
WINDOW_SPAN = 3.0  # estimates farther than this many window_m from a step do not enter its mean
FALSE_ALARM = 0.01  # chance that a drive at one pitch has any step leave the median (family-wise)
WINDOW_WIDTH = 2.0 * math.sqrt(math.pi)  # effective width of a Gaussian window, in its standard deviations
GRID_STEP = 0.25  # the local means are computed every this many window_m along the drive, then interpolated


@dataclass(frozen=True)
class HorizonTrack:
    """Per-step horizon offsets of a drive.

    Attributes:
        median_px: the drive's median horizon offset, pixels.
        offsets_px: ``(N,)`` float64 offset applied to each step, pixels: the local mean where its departure
            from the drive's level passed the gate, else the median.
        local_px: ``(N,)`` float64 local robust mean at each step (NaN where no estimate is near), pixels.
        se_px: ``(N,)`` float64 standard error of ``local_px``, pixels (inf where undetermined).
        sigma_px: robust standard deviation of the estimate of a step of 1 m about the track, pixels (that
            of a step of ``t`` metres is ``sigma_px / sqrt(t)``; NaN when not tracked).
        level_px: the same robust mean as ``local_px`` over the whole drive, pixels: the local mean is applied
            where it departs from this by more than the gate (NaN when not tracked).
    """

    median_px: float
    offsets_px: NDArray[np.float64]
    local_px: NDArray[np.float64]
    se_px: NDArray[np.float64]
    sigma_px: float
    level_px: float

    @property
    def tracked(self) -> NDArray[np.bool_]:
        """``(N,)`` bool: the step's offset is its local mean (a pitch change passed the gate), not the median."""
        return np.asarray(self.offsets_px != self.median_px)


def _huber_mean(
    values: NDArray[np.float64], prec: NDArray[np.float64], weights: NDArray[np.float64], sigma_1m: float
) -> tuple[float, float, float]:
    """Huber mean of ``values`` (precisions ``prec``, extra ``weights``): ``(mean, se, n_eff)``."""
    w0 = weights * prec
    mu, w = float(np.median(values)), w0
    for _ in range(IRLS_ITERATIONS):
        r = np.abs(values - mu) * np.sqrt(prec)  # in standard deviations of sigma_1m
        w = w0 * (np.minimum(1.0, HUBER_K * sigma_1m / np.maximum(r, 1e-12)) if sigma_1m > 0 else 1.0)
        mu = float(np.sum(w * values) / np.sum(w))
    total = float(np.sum(w))
    return mu, sigma_1m * math.sqrt(float(np.sum(w * w / prec))) / total, total**2 / float(np.sum(w * w))


def _local_means(
    estimates: NDArray[np.float64],
    travel_m: NDArray[np.float64],
    at_m: NDArray[np.float64],
    window_m: float,
    sigma_1m: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Gaussian-windowed, precision-weighted Huber means of the estimates at every step position.

    An estimate's variance is ``sigma_1m^2 / travel`` (see :func:`track_horizon`), so it weighs its travel;
    steps without travel or estimate do not count. The means are computed every ``GRID_STEP * window_m``
    metres along the drive and interpolated (a mean over a Gaussian window barely changes within a quarter
    of it), so the cost does not grow with the frame rate.

    Returns:
        ``(mean, se, n_eff)`` per step: the local mean (NaN where no estimate is near), its standard error
        (pixels, from ``sigma_1m``) and the effective number of estimates in it (Kish).
    """
    ok = np.isfinite(estimates) & (travel_m > 0)
    pos, vals, prec = at_m[ok], estimates[ok], travel_m[ok]  # sorted: travel only grows
    spacing = max(GRID_STEP * window_m, float(at_m[-1] - at_m[0]) / len(at_m))  # at most ~N + 1 means
    grid = np.arange(float(at_m[0]), float(at_m[-1]) + spacing, spacing)
    n = len(grid)
    mean, se, n_eff = np.full(n, math.nan), np.full(n, math.inf), np.zeros(n)
    lo = np.searchsorted(pos, grid - WINDOW_SPAN * window_m, side="left")
    hi = np.searchsorted(pos, grid + WINDOW_SPAN * window_m, side="right")
    for k in range(n):
        v, p = vals[lo[k] : hi[k]], prec[lo[k] : hi[k]]
        if len(v) == 0:
            continue
        gauss = np.exp(-0.5 * ((pos[lo[k] : hi[k]] - grid[k]) / window_m) ** 2)
        mean[k], se[k], n_eff[k] = _huber_mean(v, p, gauss, sigma_1m)
    known = np.isfinite(mean)
    if not known.any():
        return np.full(len(at_m), math.nan), np.full(len(at_m), math.inf), np.zeros(len(at_m))
    at_mean = np.interp(at_m, grid[known], mean[known])
    at_mean[np.interp(at_m, grid, (~known).astype(np.float64)) > 0] = math.nan  # next to a gap: no mean
    at_se = np.interp(at_m, grid[known], se[known])
    return at_mean, at_se, np.interp(at_m, grid, n_eff)


def track_horizon(
    estimates_px: NDArray[np.float64], travel_m: NDArray[np.float64], window_m: float, gate_z: float
) -> HorizonTrack | None:
    """A drive's per-step horizon offsets from its per-step estimates (see the module docstring).

    An estimate's scatter falls with the step's travel (the near-far gap it equalises grows with it): on
    the simulated mine, its standard deviation is ~25 px at 0.15 m steps and ~11 px at 0.8 m, i.e. a
    variance ``sigma_1m^2 / travel`` (``sigma_1m`` ~10 px). Each estimate therefore weighs its travel:
    every metre of floor counts once, however slowly it was driven over, and a creeping start's poor
    estimates do not pose as a pitch change.

    Args:
        estimates_px: ``(N,)`` float64 horizon offset estimated from each step, pixels; NaN where the step
            gave none (stationary, low confidence, no root).
        travel_m: ``(N,)`` float64 non-negative distance travelled in each step, metres (any consistent
            estimate: it places the steps along the drive and weighs their estimates).
        window_m: standard deviation of the Gaussian window in distance travelled, metres; ``<= 0`` keeps
            the median for every step.
        gate_z: a local mean is applied where it departs from the median by more than this many of its
            standard errors, or by more than the family-wise bound of the drive's number of independent
            windows (``FALSE_ALARM``), whichever is larger: a long drive has more chances to cross it.

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
    used = ok & (travel > 0)
    if window_m <= 0 or int(used.sum()) < MIN_ESTIMATES:
        return HorizonTrack(median, flat, flat.copy(), np.full(n, math.inf), math.nan, math.nan)
    at = np.cumsum(travel) - 0.5 * travel  # the middle of each step along the drive
    root_t = np.sqrt(travel[used])
    sigma = _mad((est[used] - median) * root_t)
    local, _, _ = _local_means(est, travel, at, window_m, sigma)
    fit = used & np.isfinite(local)  # scatter about the track, not about the median: a trend does not count
    sigma = _mad((est[fit] - local[fit]) * np.sqrt(travel[fit])) if fit.any() else sigma
    local, se, n_eff = _local_means(est, travel, at, window_m, sigma)
    # A pitch change is a local mean's departure from the same estimator over the whole drive (its level),
    # not from the median: the median weighs every frame alike, and a slow step's estimate leans high, so a
    # drive at one pitch would show departures from the median wherever it crept.
    level = _huber_mean(est[used], travel[used], np.ones(int(used.sum())), sigma)[0]
    z = max(gate_z, _family_z(float(travel.sum()) / (WINDOW_WIDTH * window_m)))
    apply = np.isfinite(local) & (n_eff >= MIN_EFFECTIVE) & (np.abs(local - level) > z * se)
    return HorizonTrack(median, np.where(apply, local, median), local, se, sigma, level)


def _family_z(windows: float) -> float:
    """Two-sided normal quantile that ``windows`` independent local means all stay within with probability
    ``1 - FALSE_ALARM`` (Bonferroni): 2.6 for one window, 3.5 for 25, 3.9 for 100."""
    return NormalDist().inv_cdf(1.0 - FALSE_ALARM / (2.0 * max(1.0, windows)))


def _mad(x: NDArray[np.float64]) -> float:
    """Robust standard deviation (1.4826 median absolute deviation from the median)."""
    return 1.4826 * float(np.median(np.abs(x - np.median(x))))


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
        hom: ``(3, 3)`` the drive's pixel -> floor (look frame, metres) ground homography.
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
    hom = np.asarray(hom, dtype=np.float64)
    counts = np.array([len(p) for p in pairs], dtype=np.int64)
    pixels = np.array([point for p in pairs for a, b in p for point in (a, b)], dtype=np.float64)
    pixels = pixels.reshape(-1, 2, 2)  # (M, previous/current, u/v) every step's matches in order
    first = np.cumsum(counts) - counts  # each step's first (ROI-centre) match
    travel = np.zeros(len(est))
    has = counts > 0
    centre = _to_floor(_shifted(hom, float(np.median(est[ok]))), pixels[first[has]])
    travel[has] = np.hypot(*(centre[:, 0] - centre[:, 1]).T)
    track = track_horizon(est, travel, window_m, gate_z)
    assert track is not None  # as many finite estimates as checked above
    # H(u, v + offset) = H(u, v) + offset * H[:, 1]: each match through its step's offset at once.
    offset = np.repeat(track.offsets_px, counts)
    h = pixels @ hom[:, :2].T + (hom[:, 1] * offset[:, None] + hom[:, 2])[:, None, :]
    on_floor = h[..., :2] / h[..., 2:3]
    floor: list[list[FloorPair]] = [
        [(on_floor[m, 0], on_floor[m, 1]) for m in range(a, a + n)]
        for a, n in zip(first.tolist(), counts.tolist(), strict=True)
    ]
    return track, floor
