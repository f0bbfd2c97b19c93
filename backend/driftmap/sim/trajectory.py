"""Timing a vehicle along planned runs: smoothing, wander, speed profile, stops; then frame poses.

A :class:`Run` is one stretch driven without changing gear: the rear-axle path (grid metres, in the
direction of travel), forward or reverse, a cruise speed and stops. :func:`time_run` smooths the
path's corners, adds a small lateral wander and heading noise (both fading to zero at the run's ends
so consecutive runs join exactly), limits speed by lateral acceleration in bends and by acceleration
and braking, and integrates time. :func:`sample_frames` samples a drive's runs at the frame rate and
returns the camera's ground truth: the floor point under the camera (``y_c`` ahead of the rear axle)
and the heading (where the front points, also when reversing).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.sim.geometry import FloatArray, arc_lengths, resample
from driftmap.sim.params import VehicleParams

__all__ = ["FramePoses", "Run", "Stop", "TimedRun", "sample_frames", "time_run"]

_DS_M = 0.1  # path sampling step
_TAPER_M = 8.0  # wander and heading noise fade in/out over this distance


@dataclass(frozen=True)
class Stop:
    """A stationary pause at the path point nearest ``xy`` (grid metres)."""

    xy: tuple[float, float]
    dwell_s: float
    label: str = ""
    grounding: bool = False  # a surveyor grounds the frame in the middle of this stop


@dataclass(frozen=True, eq=False)
class Run:
    """A stretch driven in one gear; ``path`` (N, 2) rear-axle grid metres in the direction of travel."""

    path: FloatArray
    reverse: bool
    speed_mps: float
    stops: tuple[Stop, ...] = ()  # interior stops
    end: Stop | None = None  # the pause after arriving
    wander: bool = True  # lateral wander and heading noise
    seed: int = 0  # seeds the wander of this run


@dataclass(frozen=True, eq=False)
class TimedRun:
    """Samples of a timed run: t (n,) seconds from the run's start (strictly increasing), rear-axle
    positions xy (n, 2) grid metres, yaw (n,) unwrapped radians, speed (n,) m/s, and the stops as
    (t_start, t_end, stop)."""

    t: FloatArray
    xy: FloatArray
    yaw: FloatArray
    speed: FloatArray
    events: tuple[tuple[float, float, Stop], ...]

    @property
    def duration_s(self) -> float:
        return float(self.t[-1])


def _simplify(poly: FloatArray, min_step_m: float = 0.5) -> FloatArray:
    """Drop vertices closer than ``min_step_m`` to the last kept one (the ends are kept)."""
    keep = [poly[0]]
    for p in poly[1:-1]:
        if np.hypot(*(p - keep[-1])) >= min_step_m:
            keep.append(p)
    if np.hypot(*(poly[-1] - keep[-1])) < min_step_m and len(keep) > 1:
        keep.pop()
    keep.append(poly[-1])
    return np.asarray(keep)


def _fillet(poly: FloatArray, radius_m: float) -> FloatArray:
    """Round every corner with a circular arc of ``radius_m`` (smaller where segments are short).

    Each arc is tangent to both segments, so the ends and the end directions of the path are kept;
    an arc may use half of an interior segment and all of an end segment.
    """
    pts = _simplify(poly)
    if len(pts) < 3 or radius_m <= 0:
        return pts
    seg = np.diff(pts, axis=0)
    length = np.hypot(*seg.T)
    unit = seg / length[:, None]
    out = [pts[0]]
    for i in range(1, len(pts) - 1):
        d0, d1 = unit[i - 1], unit[i]
        cross = d0[0] * d1[1] - d0[1] * d1[0]
        phi = float(np.arctan2(abs(cross), float(d0 @ d1)))
        if phi < 1e-4:
            out.append(pts[i])
            continue
        avail = min(length[i - 1] * (1.0 if i == 1 else 0.5), length[i] * (1.0 if i == len(pts) - 2 else 0.5))
        tan_half = float(np.tan(phi / 2))
        t = min(radius_m * tan_half, 0.999 * avail)
        r = t / tan_half
        a = pts[i] - t * d0
        normal = np.array([-d0[1], d0[0]]) * (1.0 if cross > 0 else -1.0)
        centre = a + r * normal
        start = np.arctan2(*(a - centre)[::-1])
        n = max(int(np.ceil(phi * r / 0.05)), 2)
        ang = start + np.sign(cross) * np.linspace(0.0, phi, n + 1)
        out.extend(centre + r * np.stack([np.cos(ang), np.sin(ang)], axis=1))
    out.append(pts[-1])
    arr = np.asarray(out)
    keep = np.concatenate([[True], np.hypot(*np.diff(arr, axis=0).T) > 1e-6])
    return np.asarray(arr[keep])


def _smooth(poly: FloatArray, radius_m: float, sigma_m: float) -> FloatArray:
    """Fillet the corners, then soften curvature steps with a Gaussian that fades out near the ends."""
    pts = resample(_fillet(poly, radius_m), _DS_M)
    if len(pts) < 3 or sigma_m <= 0:
        return pts
    sig = sigma_m / _DS_M
    r = int(3 * sig)
    k = np.exp(-0.5 * (np.arange(-r, r + 1) / sig) ** 2)
    k /= k.sum()
    d0, d1 = pts[1] - pts[0], pts[-1] - pts[-2]
    steps = np.arange(1, r + 1)[:, None]
    padded = np.concatenate([pts[0] - steps[::-1] * d0, pts, pts[-1] + steps * d1])
    smooth = np.stack([np.convolve(padded[:, i], k, mode="valid") for i in range(2)], axis=1)
    s = arc_lengths(pts)
    w = np.clip(np.minimum(s, s[-1] - s) / (3 * sigma_m), 0.0, 1.0)[:, None]
    return np.asarray(pts + w * (smooth - pts))


def _noise(
    rng: np.random.Generator, s: FloatArray, amp: float, wavelengths: tuple[float, float]
) -> FloatArray:
    """Smooth noise along s: three sinusoids of random wavelength and phase, peak ~amp."""
    out = np.zeros_like(s)
    for _ in range(3):
        lam = rng.uniform(*wavelengths)
        out += np.sin(2.0 * np.pi * s / lam + rng.uniform(0, 2 * np.pi))
    return amp * out / 2.0


def time_run(run: Run, vp: VehicleParams) -> TimedRun:
    """Smooth, perturb and time one run.

    Args:
        run: the planned run.
        vp: vehicle parameters.
    """
    pts = resample(_smooth(run.path, vp.turn_radius_m, vp.path_smoothing_m), _DS_M)
    s = arc_lengths(pts)
    total = float(s[-1])
    rng = np.random.default_rng(run.seed)
    taper = np.clip(np.minimum(s, total - s) / _TAPER_M, 0.0, 1.0)
    taper = taper * taper * (3 - 2 * taper)
    tangent = np.gradient(pts, axis=0)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    if run.wander and total > 2 * _TAPER_M:
        off = _noise(rng, s, vp.wander_m, vp.wander_wavelength_m) * taper
        pts = pts + off[:, None] * np.stack([-tangent[:, 1], tangent[:, 0]], axis=1)
        tangent = np.gradient(pts, axis=0)
        tangent /= np.maximum(np.linalg.norm(tangent, axis=1, keepdims=True), 1e-12)
    heading = np.unwrap(np.arctan2(tangent[:, 1], tangent[:, 0]))
    yaw = heading + (math.pi if run.reverse else 0.0)
    if run.wander and total > 2 * _TAPER_M:
        yaw = yaw + _noise(rng, s, vp.heading_noise_rad, (6.0, 20.0)) * taper
    # speed: curvature limit, zero at the ends and stops, acceleration and braking limits
    ds = np.maximum(np.diff(s), 1e-9)
    curvature = np.abs(np.gradient(heading, s)) if len(s) > 1 else np.zeros(1)
    v = np.minimum(run.speed_mps, np.sqrt(vp.lateral_accel_mps2 / np.maximum(curvature, 1e-6)))
    stop_idx: dict[int, list[Stop]] = {}
    for st in run.stops:
        i = int(np.argmin(np.hypot(*(pts - np.asarray(st.xy)).T)))
        if 0 < i < len(s) - 1:
            stop_idx.setdefault(i, []).append(st)
    v[[0, -1]] = 0.0
    v[list(stop_idx)] = 0.0
    for i in range(1, len(v)):
        v[i] = min(v[i], math.sqrt(v[i - 1] ** 2 + 2 * vp.accel_mps2 * ds[i - 1]))
    for i in range(len(v) - 2, -1, -1):
        v[i] = min(v[i], math.sqrt(v[i + 1] ** 2 + 2 * vp.decel_mps2 * ds[i]))
    k = np.ones(15) / 15.0
    v = np.minimum(v, np.convolve(np.pad(v, 7, mode="edge"), k, mode="valid"))
    v[[0, -1]] = 0.0
    v[list(stop_idx)] = 0.0
    mean_v = np.maximum((v[:-1] + v[1:]) / 2, 1e-3)
    t = np.concatenate([[0.0], np.cumsum(ds / mean_v)])
    # insert the dwell of every stop as a duplicated sample (same place, later time)
    last = len(s) - 1
    dwell = {i: max(max(st.dwell_s for st in sts), 0.1) for i, sts in stop_idx.items()}
    if run.end is not None:
        stop_idx[last] = [run.end]
        dwell[last] = max(run.end.dwell_s, 0.1)
    t_list: list[float] = []
    i_list: list[int] = []
    events: list[tuple[float, float, Stop]] = []
    shift = 0.0
    for i in range(len(s)):
        ti = float(t[i]) + shift
        t_list.append(ti)
        i_list.append(i)
        if i in dwell:
            events.extend((ti, ti + dwell[i], st) for st in stop_idx[i])
            shift += dwell[i]
            t_list.append(ti + dwell[i])
            i_list.append(i)
    idx = np.asarray(i_list)
    return TimedRun(np.asarray(t_list), pts[idx], yaw[idx], v[idx], tuple(events))


def _locate(r: TimedRun, tl: FloatArray) -> tuple[NDArray[np.int64], FloatArray]:
    """Sample interval j of each time and the fraction f of its distance covered by then.

    Within an interval the acceleration is constant, so distance grows quadratically in time:
    f = (v0 tau + (v1 - v0) tau^2 / (2 dt)) / ((v0 + v1) dt / 2); linear when both speeds are 0.
    """
    j = np.clip(np.searchsorted(r.t, tl, side="right") - 1, 0, len(r.t) - 2)
    dt = np.maximum(r.t[j + 1] - r.t[j], 1e-12)
    tau = np.clip(tl - r.t[j], 0.0, dt)
    v0, v1 = r.speed[j], r.speed[j + 1]
    dist = 0.5 * (v0 + v1) * dt
    quad = (v0 * tau + 0.5 * (v1 - v0) / dt * tau * tau) / np.maximum(dist, 1e-12)
    f = np.where(dist > 1e-9, quad, tau / dt)
    return j, np.clip(f, 0.0, 1.0)


@dataclass(frozen=True, eq=False)
class FramePoses:
    """Per-frame ground truth of a drive: t (n,) s, camera floor point xy (n, 2) grid m, yaw (n,) rad,
    and the groundings as (frame, surveyed x, surveyed y)."""

    t: FloatArray
    xy: FloatArray
    yaw: FloatArray
    groundings: list[tuple[int, float, float]]


def sample_frames(
    runs: list[TimedRun],
    fps: float,
    y_c_m: float,
    start_dwell_s: float,
    grounding_sigma_m: float,
    rng: np.random.Generator,
    start_grounding: bool = False,
) -> FramePoses:
    """Sample consecutive timed runs at ``fps`` after an initial pause of ``start_dwell_s``.

    Args:
        runs: the drive's runs in order; each starts where the previous ended.
        fps: frame rate.
        y_c_m: camera ahead of the rear axle.
        start_dwell_s: stationary time before the first run.
        grounding_sigma_m: standard deviation of surveyed grounding positions.
        rng: draws the grounding survey errors.
        start_grounding: also ground the frame in the middle of the initial pause.
    """
    starts = start_dwell_s + np.concatenate([[0.0], np.cumsum([r.duration_s for r in runs])])
    n = math.floor(starts[-1] * fps + 1e-9) + 1
    t = np.arange(n) / fps
    xy = np.zeros((n, 2))
    yaw = np.zeros(n)
    k = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(runs) - 1)
    for i, r in enumerate(runs):
        sel = np.flatnonzero(k == i)
        j, f = _locate(r, np.clip(t[sel] - starts[i], 0.0, r.duration_s))
        xy[sel] = r.xy[j] + f[:, None] * (r.xy[j + 1] - r.xy[j])
        yaw[sel] = r.yaw[j] + f * (r.yaw[j + 1] - r.yaw[j])
    yaw = (yaw + math.pi) % (2 * math.pi) - math.pi
    cam = xy + y_c_m * np.stack([np.cos(yaw), np.sin(yaw)], axis=1)
    spans: list[tuple[float, float]] = [(0.0, start_dwell_s)] if start_grounding else []  # grounding stops
    for i, r in enumerate(runs):
        spans += [(float(starts[i] + t0), float(starts[i] + t1)) for t0, t1, st in r.events if st.grounding]
    groundings: list[tuple[int, float, float]] = []
    for t0, t1 in spans:
        frame = min(max(round((t0 + t1) / 2 * fps), 0), n - 1)
        ex, ey = rng.normal(0.0, grounding_sigma_m, 2)
        groundings.append((frame, float(cam[frame, 0] + ex), float(cam[frame, 1] + ey)))
    return FramePoses(t, cam, yaw, groundings)
