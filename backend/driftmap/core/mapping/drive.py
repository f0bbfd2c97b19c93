"""One mapping drive's share of a map build: its visual odometry, thumbnails and frame statistics.

Stage 1 of :mod:`driftmap.core.mapping.pipeline` is independent per stretch of a drive, so a build fans it out in
segments (:func:`prepare_segment`): threads of one process, worker processes of one machine, or job workers on
several machines, and the long drives no longer bound the build. A segment starts two frames early, the
step between them only warming up the odometry's motion prior. :class:`PreparedSegment` round-trips exactly
through plain arrays (:meth:`PreparedSegment.to_arrays` / :meth:`PreparedSegment.from_arrays`) so that it can
cross a process or be kept as a blob. :func:`join_segments` then runs what needs the whole drive (the
odometry's self-calibration, dead reckoning) and gives its :class:`PreparedDrive`, bit for bit the same
wherever the segments were computed.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from driftmap.core.graph.constraints import OdometryChain
from driftmap.core.imaging.images import preprocess
from driftmap.core.imaging.lens import Lens
from driftmap.core.imaging.params import ImageParams
from driftmap.core.imaging.views import undistorted_view
from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.drive import MatchedSteps, OdometryStep, match_frames, reckon
from driftmap.core.odometry.params import OdometryParams
from driftmap.core.topomap.database import DatabaseParams, FrameStatsPass
from driftmap.core.types import F64, ProgressFn

_STATS_LISTS = ("sal", "masks", "feats", "sample", "sample_sal")  # FrameStatsPass chunk lists kept


class _Tee:
    """Yields frames to odometry while keeping the place-recognition thumbnails and feeding the database's
    frame statistics (when given) of all but the first ``skip`` frames, so each frame is decoded once.

    Thumbnails and statistics see the camera's thumbnail view (:func:`~driftmap.core.imaging.views.undistorted_view`;
    the recorded frame when ``lens`` is None); odometry gets the recorded frame and undistorts its own window.
    """

    def __init__(
        self,
        frames: Iterable[NDArray[np.uint8]],
        params: ImageParams,
        stats: FrameStatsPass | None,
        report: tuple[ProgressFn, int] | None,
        skip: int = 0,
        lens: Lens | None = None,
    ) -> None:
        self._frames, self._params, self.stats, self._report = frames, params, stats, report
        self._skip, self._lens = skip, lens
        self.thumbs: list[NDArray[np.float32]] = []

    def __iter__(self) -> Iterator[NDArray[np.uint8]]:
        for k, frame in enumerate(self._frames):
            if k >= self._skip:
                view = undistorted_view(frame, self._lens)
                self.thumbs.append(preprocess(view, self._params))
                if self.stats is not None:
                    self.stats.add(view)
                if self._report is not None:
                    self._report[0]("odometry", len(self.thumbs) / max(self._report[1], 1))
            yield frame


@dataclass(frozen=True, eq=False)
class PreparedDrive:
    """Stage 1 of one drive.

    Attributes:
        chain: the odometry chain (steps (N-1, 3), sigmas (N-1, 3)) for the pose graph.
        raw_poses: (N, 3) float64 dead-reckoned poses [x_m, y_m, yaw_rad] from the drive's start pose.
        confidence: (N,) float64 odometry confidence of the step into each frame (1 for frame 0).
        thumbs: (N, h, w) float32 patch-normalised place-recognition thumbnails.
        stats: the closed per-drive pass of the database's frame statistics (None when the database is off).
        seconds: work time of its segments, summed, seconds.
    """

    chain: OdometryChain
    raw_poses: F64
    confidence: F64
    thumbs: NDArray[np.float32]
    stats: FrameStatsPass | None
    seconds: float

    @property
    def n_frames(self) -> int:
        """Frames N of the drive."""
        return int(self.raw_poses.shape[0])


_STEP_FIELDS = 11  # dx, dtheta, shift x, shift y, confidence, stationary, sigma xy, sigma theta, prev_T_curr


def _steps_array(steps: Sequence[OdometryStep]) -> F64:
    rows = [
        (s.dx_m, s.dtheta_rad, *s.shift_px, s.confidence, float(s.stationary), s.sigma_xy_m, s.sigma_theta_rad,
         *s.prev_T_curr)
        for s in steps
    ]  # fmt: skip
    return np.array(rows, dtype=np.float64).reshape(-1, _STEP_FIELDS)


def _array_steps(rows: F64, model: str) -> list[OdometryStep]:
    return [
        OdometryStep(
            dx_m=float(r[0]), dtheta_rad=float(r[1]), shift_px=(float(r[2]), float(r[3])), confidence=float(r[4]),
            stationary=bool(r[5]), sigma_xy_m=float(r[6]), sigma_theta_rad=float(r[7]),
            prev_T_curr=(float(r[8]), float(r[9]), float(r[10])), model=model,
        )
        for r in rows
    ]  # fmt: skip


def _pairs_array(pairs: Sequence[Sequence[tuple[NDArray, NDArray]]]) -> tuple[F64, NDArray[np.int8]]:
    """``(S, 3, 2, 2)`` matched pixels ([match][previous/current][x/y], NaN where absent) and ``(S,)`` counts."""
    out = np.full((len(pairs), 3, 2, 2), np.nan)
    counts = np.array([len(p) for p in pairs], dtype=np.int8)
    for k, step in enumerate(pairs):
        for j, (a, b) in enumerate(step):
            out[k, j, 0], out[k, j, 1] = a, b
    return out, counts


@dataclass(frozen=True, eq=False)
class PreparedSegment:
    """Stage 1 of the frames ``[first, stop)`` of one drive: the unit a build fans out.

    Attributes:
        first: the drive's index of the segment's first frame.
        matched: the steps into frames ``max(first, 1) .. stop - 1``, before the drive's self-calibration
            (which needs every step of the drive: :func:`join_segments`).
        thumbs: ``(stop - first, h, w)`` float32 patch-normalised place-recognition thumbnails.
        stats: the closed pass of the database's frame statistics over these frames (None when off).
        seconds: wall time of the work, seconds.
    """

    first: int
    matched: MatchedSteps
    thumbs: NDArray[np.float32]
    stats: FrameStatsPass | None
    seconds: float

    @property
    def stop(self) -> int:
        """One past the drive's index of the segment's last frame."""
        return self.first + int(self.thumbs.shape[0])

    def to_arrays(self) -> dict[str, NDArray]:
        """Every field as named arrays (for ``np.savez``); :meth:`from_arrays` restores them exactly."""
        steps = self.matched.steps
        pairs, counts = _pairs_array(self.matched.pairs)
        out: dict[str, NDArray] = {
            "first": np.array(self.first),
            "steps": _steps_array(steps),
            "model": np.array(steps[0].model if steps else ""),
            "pairs": pairs,
            "pair_counts": counts,
            "ms_per_step": self.matched.ms_per_step,
            "frames": np.array(self.matched.frames),
            "horizon_px": self.matched.horizon_px,
            "thumbs": self.thumbs,
            "seconds": np.array(self.seconds),
        }
        if self.stats is not None:  # where the classifier's sample was taken: see restride_segment
            out["stats_first"] = np.array(self.stats.seen - self.stats.frames)
            out["stats_stride"] = np.array(self.stats.stride)
            for name in _STATS_LISTS:
                chunks = getattr(self.stats, name)
                if chunks:  # one array: concatenating chunks is exact, as finish_frame_stats does
                    out[f"stats_{name}"] = np.concatenate(chunks)
        return out

    @classmethod
    def from_arrays(
        cls,
        arrays: dict[str, NDArray],
        database: DatabaseParams,
        images: ImageParams,
        offset: int,
        total: int,
    ) -> PreparedSegment:
        """The piece stored by :meth:`to_arrays`; ``database``, ``images`` and ``offset``/``total`` (flat index
        of the segment's first frame, frames of the build) as given to :func:`prepare_segment`."""
        thumbs = np.asarray(arrays["thumbs"], dtype=np.float32)
        stats = None
        if database.enabled:
            stats = FrameStatsPass(offset, total, database, images)
            for name in _STATS_LISTS:
                key = f"stats_{name}"
                setattr(stats, name, [np.asarray(arrays[key])] if key in arrays else [])
            stats.frames, stats.seen = thumbs.shape[0], offset + thumbs.shape[0]
        pairs, counts = np.asarray(arrays["pairs"]), np.asarray(arrays["pair_counts"])
        matched = MatchedSteps(
            _array_steps(np.asarray(arrays["steps"]), str(arrays["model"])),
            [
                [(pairs[k, j, 0], pairs[k, j, 1]) for j in range(int(counts[k]))]
                for k in range(counts.shape[0])
            ],
            np.asarray(arrays["ms_per_step"], dtype=np.float64),
            int(arrays["frames"]),
            np.asarray(arrays["horizon_px"], dtype=np.float64),
        )
        return cls(int(arrays["first"]), matched, thumbs, stats, float(arrays["seconds"]))


def prepare_segment(
    name: str,
    frames: Iterable[NDArray[np.uint8]],
    span: tuple[int, int],
    camera: CameraModel,
    odometry: OdometryParams,
    images: ImageParams,
    *,
    stats: FrameStatsPass | None = None,
    report: ProgressFn | None = None,
) -> PreparedSegment:
    """Stage 1 of the frames ``span = (first, stop)`` of one drive: steps, thumbnails and (when ``stats``
    is given) frame statistics.

    Args:
        name: the drive's name (for errors).
        frames: the drive's gray (H, W) uint8 frames ``segment_begin(first) .. stop - 1`` in time order: a
            segment inside a drive starts two frames early, the step between them warming up the motion
            prior (and the next giving the step into ``first``).
        span: ``(first, stop)``, the drive's indices of the segment's frames.
        camera: its calibrated camera; with a lens, thumbnails and statistics are taken of its thumbnail view
            (:mod:`driftmap.core.imaging.views`).
        odometry: visual-odometry parameters.
        images: place-recognition pre-processing of the thumbnails.
        stats: a fresh :class:`FrameStatsPass` of this segment (its flat offset, the build's total); closed here.
        report: called with ``("odometry", fraction of the segment's frames processed)``.

    Raises:
        ValueError: the frames given do not cover the span.
    """
    first, stop = span
    begin = segment_begin(first)
    start = time.perf_counter()
    progress = (report, stop - first) if report is not None else None
    tee = _Tee(frames, images, stats, progress, first - begin, camera.lens)
    matched = match_frames(tee, camera, odometry, warm_up=max(0, first - begin - 1), first_index=begin)
    if len(tee.thumbs) != stop - first:
        raise ValueError(f"drive {name!r}: frames {first}..{stop - 1} asked for, {len(tee.thumbs)} given")
    if stats is not None:
        stats.close()
    thumbs = np.stack(tee.thumbs) if tee.thumbs else np.zeros((0, 0, 0), dtype=np.float32)
    return PreparedSegment(first, matched, thumbs, stats, time.perf_counter() - start)


def segment_begin(first: int) -> int:
    """The first frame a segment starting at frame ``first`` is given (two early, for the warm-up)."""
    return max(0, first - 2)


def join_segments(
    name: str,
    segments: Sequence[PreparedSegment],
    n_frames: int,
    camera: CameraModel,
    odometry: OdometryParams,
    start_wT: tuple[float, float, float] = (0.0, 0.0, 0.0),
) -> PreparedDrive:
    """One drive's segments, in order and covering frames ``0 .. n_frames - 1``, as its stage-1 piece: the
    drive's self-calibration over all its steps, dead reckoning from ``start_wT``, the frame statistics.

    Raises:
        ValueError: the segments leave a gap or overlap, or do not cover the drive.
    """
    stops = [0] + [s.stop for s in segments]
    if [s.first for s in segments] != stops[:-1] or stops[-1] != n_frames or not segments:
        spans = [(s.first, s.stop) for s in segments]
        raise ValueError(f"drive {name!r}: segments {spans} do not cover its {n_frames} frames")
    matched = MatchedSteps(
        [step for s in segments for step in s.matched.steps],
        [pair for s in segments for pair in s.matched.pairs],
        np.concatenate([s.matched.ms_per_step for s in segments]),
        n_frames,
        np.concatenate([s.matched.horizon_px for s in segments]),
    )
    reckoning = reckon(matched, camera, odometry, start_wT)
    steps = reckoning.steps
    iTj = np.array([s.prev_T_curr for s in steps], dtype=np.float64).reshape(-1, 3)
    sigmas = np.array([[s.sigma_xy_m, s.sigma_xy_m, s.sigma_theta_rad] for s in steps]).reshape(-1, 3)
    confidence = np.concatenate([[1.0], [s.confidence for s in steps]])
    passes = [s.stats for s in segments]
    stats = None
    if all(p is not None for p in passes):
        stats = _merged([p for p in passes if p is not None])
    return PreparedDrive(
        OdometryChain(iTj, sigmas),
        reckoning.wTi,
        confidence,
        np.concatenate([s.thumbs for s in segments]),
        stats,
        sum(s.seconds for s in segments),
    )


def _merged(passes: Sequence[FrameStatsPass]) -> FrameStatsPass:
    """One drive's frame-statistics pass from its consecutive segments' (chunk lists concatenated: segments
    start on chunk boundaries, so the chunks are those of one pass over the drive)."""
    merged = copy.copy(passes[0])  # parameters and sampling stride; the closed passes hold no batch
    for name in _STATS_LISTS:
        setattr(merged, name, [chunk for p in passes for chunk in getattr(p, name)])
    merged.frames = sum(p.frames for p in passes)
    merged.seen = passes[-1].seen
    return merged
