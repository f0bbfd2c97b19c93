"""Tests of driftmap.core.odometry.pitch: the horizon (pitch) tracked along a drive."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from driftmap.core.odometry.drive import dead_reckon, shift_horizon
from driftmap.core.odometry.params import ODOMETRY_DEFAULT
from driftmap.core.odometry.pitch import MIN_EFFECTIVE, horizon_floor, track_horizon
from tests.core.odometry.test_drive import arc_step, floor_texture, pinhole_camera, render

NOISE_PX = 4.0  # scatter of the horizon estimate of a 1 m step (KITTI: 4-8 px; simulated mine ~10 px)
WINDOW_M = 12.0
GATE_Z = 3.0


def noisy(truth_px: np.ndarray, travel_m: float = 0.5, seed: int = 3, outliers: float = 0.0) -> np.ndarray:
    """Per-step estimates: the truth plus Gaussian noise (variance NOISE_PX^2 / travel), a fraction of wild
    values, some steps without one."""
    rng = np.random.default_rng(seed)
    est = truth_px + NOISE_PX / math.sqrt(travel_m) * rng.standard_normal(len(truth_px))
    wild = rng.random(len(est)) < outliers
    est[wild] = rng.uniform(-40.0, 40.0, int(wild.sum()))
    est[rng.random(len(est)) < 0.1] = math.nan
    return est


class TestTrackHorizon:
    def test_one_pitch_keeps_the_median(self) -> None:
        """A drive at one pitch (ride bounce only): chance departures of the local means stay inside the
        gate, every step gets the drive's median."""
        for seed in range(5):
            est = noisy(np.full(300, 6.0), seed=seed)
            track = track_horizon(est, np.full(300, 0.5), WINDOW_M, GATE_Z)
            assert track is not None
            assert not track.tracked.any()
            assert np.all(track.offsets_px == pytest.approx(float(np.nanmedian(est))))
            assert track.sigma_px == pytest.approx(NOISE_PX, rel=0.25)

    def test_a_ramp_is_followed_where_it_leaves_the_median(self) -> None:
        """The horizon falls 30 -> 0 px over 100 m (KITTI clip 2: ~30 -> ~5 px over 50 m): the tracked
        offsets follow it at both ends, where one median for the drive is ~15 px off."""
        n, step = 200, 0.5
        truth = np.linspace(30.0, 0.0, n)
        track = track_horizon(noisy(truth), np.full(n, step), WINDOW_M, GATE_Z)
        assert track is not None
        ends = np.r_[0:40, n - 40 : n]
        assert track.tracked[ends].all()
        assert np.abs(track.offsets_px[ends] - truth[ends]).max() < 6.0  # a one-sided window lags at the ends
        assert np.abs(track.offsets_px - truth).mean() < 0.5 * np.abs(track.median_px - truth).mean()
        assert track.sigma_px == pytest.approx(NOISE_PX, rel=0.25)  # the trend does not count as noise

    def test_outliers_do_not_move_it(self) -> None:
        truth = np.where(np.arange(200) < 100, 0.0, 12.0)
        clean = track_horizon(noisy(truth, seed=5), np.full(200, 0.5), WINDOW_M, GATE_Z)
        dirty = track_horizon(noisy(truth, seed=5, outliers=0.15), np.full(200, 0.5), WINDOW_M, GATE_Z)
        assert clean is not None and dirty is not None
        far = np.r_[0:60, 140:200]  # away from the step, where the window straddles it
        assert np.abs(dirty.offsets_px[far] - truth[far]).max() < 4.0
        assert np.abs(dirty.offsets_px[far] - clean.offsets_px[far]).max() < 2.5

    def test_standing_still_does_not_widen_the_window(self) -> None:
        """Distance, not time: steps standing still (no travel, no estimate) do not stretch the window."""
        n = 240
        truth = np.where(np.arange(n) < n // 2, 0.0, 15.0)
        still = (np.arange(n) > 40) & (np.arange(n) < 100)
        est = noisy(truth, 1.0)
        est[still] = math.nan
        track = track_horizon(est, np.where(still, 0.0, 1.0), 4.0, GATE_Z)
        assert track is not None and track.tracked.any()
        assert np.abs(track.offsets_px[10:40] - 0.0).max() < 4.0  # 1 to 21 m before the change, not 80 steps
        assert np.abs(track.offsets_px[150:225] - 15.0).max() < 4.0

    def test_creeping_steps_weigh_their_travel(self) -> None:
        """A drive at one pitch whose vehicle creeps for 80 frames (5 cm steps, as at a start or in a queue):
        those steps' estimates scatter widely and lean high (the simulated mine: ~15 px at 0.1-0.2 m steps),
        but they cover 4 m of floor, and weigh as much, not as much as 80 full steps would."""
        n = 300
        travel = np.where((np.arange(n) >= 100) & (np.arange(n) < 180), 0.05, 0.5)
        rng = np.random.default_rng(8)
        est = NOISE_PX / np.sqrt(travel) * rng.standard_normal(n) + np.where(travel < 0.1, 15.0, 0.0)
        track = track_horizon(est, travel, WINDOW_M, GATE_Z)
        assert track is not None and not track.tracked.any()
        unweighted = track_horizon(est, np.full(n, 0.5), WINDOW_M, GATE_Z)  # as if each frame were 0.5 m
        assert unweighted is not None and unweighted.tracked[100:180].any()

    def test_sparse_evidence_keeps_the_median(self) -> None:
        """Where fewer than MIN_EFFECTIVE estimates fall in the window, the step keeps the median."""
        est = np.full(100, math.nan)
        est[:50] = 0.0
        est[50 : 50 + int(MIN_EFFECTIVE) - 4] = 20.0
        track = track_horizon(est, np.full(100, 1.0), 1.0, GATE_Z)
        assert track is not None
        assert np.all(track.offsets_px[60:] == track.median_px)

    def test_window_zero_is_one_median(self) -> None:
        track = track_horizon(np.linspace(0.0, 30.0, 50), np.full(50, 1.0), 0.0, GATE_Z)
        assert track is not None and np.all(track.offsets_px == 15.0)

    def test_too_few_estimates_and_bad_inputs(self) -> None:
        assert track_horizon(np.array([1.0, 2.0, math.nan]), np.ones(3), WINDOW_M, GATE_Z) is None
        with pytest.raises(ValueError, match=r"\(N,\)"):
            track_horizon(np.ones(4), np.ones(3), WINDOW_M, GATE_Z)
        with pytest.raises(ValueError, match="travel_m"):
            track_horizon(np.ones(4), np.array([1.0, -1.0, 1.0, 1.0]), WINDOW_M, GATE_Z)


class TestHorizonFloor:
    def test_each_step_through_its_own_horizon(self) -> None:
        cam = pinhole_camera()
        hom = np.asarray(cam.homography())
        n = 60
        rng = np.random.default_rng(0)
        pairs = [[(np.array([160.0, 180.0]), np.array([161.0, 195.0]))] for _ in range(n)]
        truth = np.where(np.arange(n) < 30, 0.0, 10.0)
        est = truth + 0.3 * rng.standard_normal(n)
        out = horizon_floor(hom, pairs, est, 3.0, GATE_Z)
        assert out is not None
        track, floor = out
        for k in (5, 55):
            shifted = np.asarray(shift_horizon(cam, float(track.offsets_px[k])).homography())
            a, b = pairs[k][0]
            for px, f in zip((a, b), floor[k][0], strict=True):
                h = shifted @ [px[0], px[1], 1.0]
                assert np.allclose(f, h[:2] / h[2])
        assert abs(track.offsets_px[5]) < 1.0 and abs(track.offsets_px[55] - 10.0) < 1.0
        assert horizon_floor(hom, pairs[:2], est[:2], 3.0, GATE_Z) is None
        with pytest.raises(ValueError, match="estimates"):
            horizon_floor(hom, pairs, est[:-1], 3.0, GATE_Z)


def test_dead_reckon_recovers_a_pitch_change() -> None:
    """Synthetic bird's-eye drive whose camera pitches down by ~1.8 degrees (8 px of horizon at f = 250 px)
    after 40 % of the way, as on entering a ramp: with the pitch tracked, the step lengths of both stretches
    are right; one median horizon (the pitched stretch's, the majority) reads the first stretch's steps
    wrong."""
    tex = floor_texture()
    cam = pinhole_camera()
    change_px, n, d = 8.0, 30, 0.25
    poses = [(-5.0, -0.4, 0.0)]
    for k in range(n - 1):
        poses.append(arc_step(poses[-1], d, 0.01 * math.sin(k / 4), cam.y_c_m))
    offsets = [0.0 if k < 0.4 * n else change_px for k in range(n)]
    frames = np.stack(
        [render(tex, shift_horizon(cam, off), p) for off, p in zip(offsets, poses, strict=True)]
    )
    tracked = dataclasses.replace(ODOMETRY_DEFAULT, pitch_window_m=1.0)
    one = dataclasses.replace(ODOMETRY_DEFAULT, pitch_window_m=0.0)
    runs = [dead_reckon(frames, cam, p, poses[0]) for p in (tracked, one)]
    first = slice(1, int(0.4 * n) - 2)  # steps within the first stretch, away from the change
    errs = [np.abs(np.array([s.dx_m for s in r.steps])[first] - d).mean() for r in runs]
    assert runs[1].horizon_offset_px == pytest.approx(change_px, abs=1.5)
    assert errs[0] < 0.004 and errs[1] > 2.5 * errs[0]
    truth = np.array(poses)
    end = [float(np.linalg.norm(r.wTi[-1, :2] - truth[-1, :2])) for r in runs]
    assert end[0] < 0.6 * end[1]
