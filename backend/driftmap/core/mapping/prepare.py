"""Stages 1-3 of a map build ([SSLAM], III-A): per-drive odometry, keyframes, loop-closure search.

The inputs of a build (:class:`MappingDrive`, :class:`MappingParams` and its presets) live here too.
Stage 1 is independent per drive segment (:func:`prepare_segment`, joined per drive by :func:`join_segments`);
:func:`prepare_drives` runs it in threads of this process, and :func:`join_drives` takes pieces computed
anywhere (worker processes, job workers) and runs stages 2-3 on them, with results bit-identical to the
one-process build.
"""

from __future__ import annotations

import copy
import itertools
import time
from collections.abc import Callable, Iterable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from driftmap.core.graph.constraints import POSEGRAPH_DEFAULT, OdometryChain, PoseGraphParams
from driftmap.core.imaging.images import downsample
from driftmap.core.imaging.params import IMAGES_DEFAULT, ImageParams
from driftmap.core.imaging.views import undistorted_view
from driftmap.core.loop_closure.params import LOOPS_DEFAULT, LOOPS_FAST, LoopParams
from driftmap.core.loop_closure.search import LoopMatch, detect_loops
from driftmap.core.mapping import drive as drive_prep
from driftmap.core.mapping.drive import PreparedDrive, PreparedSegment, segment_begin
from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.params import ODOMETRY_DEFAULT, ODOMETRY_FAST, OdometryParams
from driftmap.core.topomap.database import (
    DATABASE_DEFAULT,
    STATS_CHUNK,
    DatabaseParams,
    FrameStats,
    FrameStatsPass,
    finish_frame_stats,
)
from driftmap.core.topomap.model import TOPOMAP_PAPER, TopoMapParams
from driftmap.core.types import F64, ProgressFn


@dataclass(frozen=True, eq=False)
class MappingDrive:
    """One mapping drive as the pipeline needs it.

    Attributes:
        name: the drive's name (for reports).
        camera: its calibrated camera.
        t_s: (N,) float64 frame times, seconds.
        frames: returns a fresh iterator over the N gray (H, W) uint8 frames in time order.
        groundings: (frame position 0..N-1, surveyed x_m, surveyed y_m) of each grounded frame.
        start_wT: optional known pose of the first frame; used only by variants without groundings.
        frame_range: optional ``(begin, stop)`` -> iterator over frames ``begin .. stop - 1`` without
            reading those before (segments of the drive); without it they are skipped from ``frames``.
    """

    name: str
    camera: CameraModel
    t_s: F64
    frames: Callable[[], Iterable[NDArray[np.uint8]]]
    groundings: Sequence[tuple[int, float, float]] = ()
    start_wT: tuple[float, float, float] | None = None
    frame_range: Callable[[int, int], Iterable[NDArray[np.uint8]]] | None = None

    @property
    def n_frames(self) -> int:
        """Its number of frames N."""
        return int(self.t_s.shape[0])

    def frames_between(self, begin: int, stop: int) -> Iterable[NDArray[np.uint8]]:
        """Frames ``begin .. stop - 1``."""
        if self.frame_range is not None:
            return self.frame_range(begin, stop)
        return itertools.islice(self.frames(), begin, stop)


@dataclass(frozen=True)
class MappingParams:
    """Every knob of a map build; presets below."""

    odometry: OdometryParams = ODOMETRY_DEFAULT  # ground-plane VO (eq. 1, 2)
    images: ImageParams = IMAGES_DEFAULT  # place-recognition pre-processing (IV-C)
    loops: LoopParams = LOOPS_DEFAULT  # loop-closure search (eq. 3)
    graph: PoseGraphParams = POSEGRAPH_DEFAULT  # pose-graph back end
    topomap: TopoMapParams = TOPOMAP_PAPER  # map compression (III-A-4)
    database: DatabaseParams = DATABASE_DEFAULT  # each node's reference frames: SESAME + quality filter
    keyframe_spacing_m: float = 1.0  # odometry travel between keyframes used for loop closure, metres
    grounding_sigma_m: float = 0.5  # surveyor click accuracy, metres
    use_loop_closures: bool = True  # Table I variants switch these two off
    use_groundings: bool = True
    calibration_rounds: int = 5  # most odometry self-calibration passes (scale, heading rate)
    calibration_window_m: float = 15.0  # travel per window when fitting the calibration, metres
    segment_frames: int = 512  # stage 1 runs on drive segments of at most this many frames (a multiple of
    #                            the database's STATS_CHUNK): the unit a build fans out

    def __post_init__(self) -> None:
        if self.segment_frames < STATS_CHUNK or self.segment_frames % STATS_CHUNK:
            raise ValueError(f"MappingParams.segment_frames must be a multiple of {STATS_CHUNK}")


MAPPING_PAPER = MappingParams()
MAPPING_DEFAULT = MAPPING_PAPER
MAPPING_FAST = MappingParams(odometry=ODOMETRY_FAST, loops=LOOPS_FAST, keyframe_spacing_m=2.0)
MAP_PRESETS: dict[str, MappingParams] = {"paper": MAPPING_PAPER, "fast": MAPPING_FAST}
"""The parameter sets a build can be asked for by name (``--preset`` of the CLI, ``preset`` of a job)."""


def _keyframes(wTi: F64, spacing_m: float) -> NDArray[np.int64]:
    """Frame positions at every ``spacing_m`` of travelled path (frame 0 always)."""
    steps = np.linalg.norm(np.diff(wTi[:, :2], axis=0), axis=1)
    travelled = np.concatenate([[0.0], np.cumsum(steps)])
    slot = np.floor(travelled / spacing_m).astype(np.int64)
    return np.flatnonzero(np.concatenate([[True], slot[1:] != slot[:-1]])).astype(np.int64)


@dataclass(frozen=True, eq=False)
class PreparedDrives:
    """What every Table I variant shares: odometry, thumbnails, keyframes and closure candidates.

    Attributes:
        chains: per drive, the odometry chain (steps and sigmas) for the pose graph.
        raw_poses: per drive, (N_d, 3) dead-reckoned poses from ``start_wT`` or the origin.
        confidence: per drive, (N_d,) odometry confidence of the step into each frame (1 for frame 0).
        thumbs: per drive, (N_d, h, w) float32 patch-normalised thumbnails.
        keyframes: per drive, frame positions used for loop closure.
        closures: closures found between keyframes (empty when loop closure is off).
        timings: seconds per stage.
        frame_stats: the database's frame statistics, computed in the odometry pass (None when the
            database is off); valid for the ``frame_stats_params`` (database, image) parameters.
    """

    chains: tuple[OdometryChain, ...]
    raw_poses: tuple[F64, ...]
    confidence: tuple[F64, ...]
    thumbs: tuple[NDArray[np.float32], ...]
    keyframes: tuple[NDArray[np.int64], ...]
    closures: tuple[LoopMatch, ...]
    timings: dict[str, float]
    frame_stats: FrameStats | None = None
    frame_stats_params: tuple[DatabaseParams, ImageParams] | None = None


def drive_segments(n_frames: int, max_frames: int) -> list[tuple[int, int]]:
    """``(first, stop)`` frame spans cutting a drive of ``n_frames`` into as few segments of at most
    ``max_frames`` as possible; all but the last have one length, the smallest multiple of ``STATS_CHUNK``
    that keeps their number (3,282 frames, at most 512: six of 512 and one of 210)."""
    count = max(1, -(-n_frames // max_frames))
    size = max(1, -(-n_frames // (count * STATS_CHUNK))) * STATS_CHUNK
    return [(first, min(first + size, n_frames)) for first in range(0, max(n_frames, 1), size)]


def build_segments(
    drives: Sequence[MappingDrive], params: MappingParams
) -> list[tuple[int, tuple[int, int]]]:
    """Every segment of a build: (drive position, ``(first, stop)``), drive by drive in order."""
    return [
        (k, span) for k, d in enumerate(drives) for span in drive_segments(d.n_frames, params.segment_frames)
    ]


def prepare_segment(
    drive: MappingDrive,
    params: MappingParams,
    flat: tuple[int, int],
    span: tuple[int, int],
    report: ProgressFn | None = None,
) -> PreparedSegment:
    """Stage 1 of the frames ``span = (first, stop)`` of a drive (:func:`driftmap.core.mapping.drive.prepare_segment`).

    Args:
        drive: the mapping drive.
        params: pipeline parameters (odometry, images, database).
        flat: (flat index of the drive's first frame, frames of all drives of the build) for the
            database's frame statistics.
        span: one of :func:`drive_segments` of the drive.
        report: called with ``("odometry", fraction of the segment's frames processed)``.
    """
    db = params.database
    stats = FrameStatsPass(flat[0] + span[0], flat[1], db, params.images) if db.enabled else None
    return drive_prep.prepare_segment(
        drive.name,
        drive.frames_between(segment_begin(span[0]), span[1]),
        span,
        drive.camera,
        params.odometry,
        params.images,
        stats=stats,
        report=report,
    )


def join_segments(
    drive: MappingDrive, segments: Sequence[PreparedSegment], params: MappingParams
) -> PreparedDrive:
    """A drive's piece from its segments (:func:`driftmap.core.mapping.drive.join_segments`)."""
    return drive_prep.join_segments(
        drive.name, segments, drive.n_frames, drive.camera, params.odometry, drive.start_wT or (0.0, 0.0, 0.0)
    )


def restride_segment(
    segment: PreparedSegment,
    drive: MappingDrive,
    params: MappingParams,
    sampled: tuple[int, int] | None,
) -> PreparedSegment:
    """A segment prepared by another build, its classifier sample retaken as this build takes it.

    Everything in a piece depends on its drive alone except the quality classifier's candidate sample: the
    frame statistics keep every ``stride``-th frame of the build's flat frame index, the stride set by the
    build's total frame count (:class:`~driftmap.core.topomap.database.FrameStatsPass`). A piece kept from
    a build with other drives before it, or another total, sampled other frames; this re-decodes the few
    frames the sample takes now (about ``4 * quality_sources`` over the whole build) and gives the segment
    :func:`prepare_segment` would have given.

    Args:
        segment: the kept piece, loaded with this build's flat offset and total
            (:meth:`PreparedSegment.from_arrays`).
        drive: its drive (frames read for the new sample).
        params: the build's parameters.
        sampled: (flat index of the segment's first frame, stride) of the build that prepared it; None when
            unknown (the sample is retaken).
    """
    stats = segment.stats
    if stats is None or not params.database.use_quality:
        return segment
    first_flat = stats.seen - stats.frames
    if sampled == (first_flat, stats.stride):
        return segment
    n = int(segment.thumbs.shape[0])
    pick = np.flatnonzero((first_flat + np.arange(n)) % stats.stride == 0)
    views = [
        undistorted_view(
            next(iter(drive.frames_between(segment.first + i, segment.first + i + 1))), drive.camera.lens
        )
        for i in pick.tolist()
    ]
    w, h = params.database.quality.feature_size_px
    sample = downsample(np.stack(views), (w, h)) if views else np.zeros((0, h, w), dtype=np.uint8)
    sal = np.concatenate(stats.sal) if stats.sal else np.zeros(0, dtype=np.float64)
    retaken = copy.copy(stats)
    retaken.sample, retaken.sample_sal = [sample], [sal[pick]]
    return replace(segment, stats=retaken)


def flat_offsets(drives: Sequence[MappingDrive]) -> list[tuple[int, int]]:
    """Per drive, (flat index of its first frame, frames of all drives): the ``flat`` of :func:`prepare_segment`."""
    counts = [int(d.t_s.shape[0]) for d in drives]
    offsets = np.r_[0, np.cumsum(counts)].astype(int)
    return [(int(offsets[k]), int(offsets[-1])) for k in range(len(drives))]


def prepare_drives(
    drives: Sequence[MappingDrive],
    params: MappingParams = MAPPING_DEFAULT,
    progress: ProgressFn | None = None,
    workers: int = 1,
) -> PreparedDrives:
    """Stages 1-3: visual odometry and thumbnails of every frame, keyframes, loop-closure search.

    Args:
        drives: every mapping drive of the site.
        params: pipeline parameters (``use_loop_closures`` off skips the search).
        progress: called with (stage name, fraction 0..1 of that stage), from the calling thread.
        workers: drive segments dead-reckoned at once in threads of this process (the odometry is mostly
            Python-bound: for more cores, run :func:`prepare_segment` in processes, then
            :func:`join_segments` and :func:`join_drives`).

    Raises:
        ValueError: no drive, or a drive whose frame count disagrees with its times.
    """
    if not drives:
        raise ValueError("a map build needs at least one mapping drive")
    report = progress or (lambda _stage, _fraction: None)
    start = time.perf_counter()
    report("odometry", 0.0)
    segments = build_segments(drives, params)
    flats = flat_offsets(drives)
    with ThreadPoolExecutor(max(1, min(workers, len(segments)))) as pool:
        futures = [pool.submit(prepare_segment, drives[k], params, flats[k], span) for k, span in segments]
        for done, _ in enumerate(as_completed(futures), start=1):
            report("odometry", done / len(futures))
        done_segments = [f.result() for f in futures]
    pieces = [
        join_segments(d, [s for (j, _span), s in zip(segments, done_segments, strict=True) if j == k], params)
        for k, d in enumerate(drives)
    ]
    return join_drives(pieces, drives, params, progress, time.perf_counter() - start)


def join_drives(
    pieces: Sequence[PreparedDrive],
    drives: Sequence[MappingDrive],
    params: MappingParams = MAPPING_DEFAULT,
    progress: ProgressFn | None = None,
    odometry_s: float = float("nan"),
    closures: tuple[Sequence[LoopMatch], float] | None = None,
) -> PreparedDrives:
    """Stages 2-3 on the drives' stage-1 pieces (computed anywhere): frame statistics, keyframes, loops.

    Args:
        pieces: per drive, in drive order, :func:`join_segments` of its segments prepared with the same
            ``params``.
        drives: the mapping drives.
        params: pipeline parameters.
        progress: called with (stage name, fraction 0..1 of that stage).
        odometry_s: wall time stage 1 took, seconds (reported in the build's figures).
        closures: (the closures, wall seconds) of a loop-closure search already made elsewhere on
            :func:`loop_inputs` of these pieces (a build's ``map.loops`` subtasks); None: search here.

    Raises:
        ValueError: no drive, or not one piece per drive.
    """
    if not drives or len(pieces) != len(drives):
        raise ValueError(f"a map build needs one prepared piece per drive: {len(pieces)} for {len(drives)}")
    report = progress or (lambda _stage, _fraction: None)
    timings: dict[str, float] = {"odometry_s": odometry_s}
    counts = [p.n_frames for p in pieces]
    db = params.database
    stats = None
    if db.enabled:  # the classifier of the database's quality filter, from the frames seen above
        start = time.perf_counter()
        passes = [p.stats for p in pieces]
        if any(s is None for s in passes):
            raise ValueError("the database is on, but a prepared drive has no frame statistics")
        stats = finish_frame_stats([s for s in passes if s is not None], counts, db, params.images)
        timings["frame_stats_s"] = time.perf_counter() - start

    start = time.perf_counter()
    keyframes, key_thumbs, key_times = loop_inputs(pieces, drives, params)
    found: tuple[LoopMatch, ...] = ()
    if params.use_loop_closures and closures is not None:
        found, timings["loop_closure_s"] = tuple(closures[0]), closures[1]
    else:
        if params.use_loop_closures:
            report("loop closure", 0.0)
            found = tuple(detect_loops(key_thumbs, params.loops, key_times).closures)
        timings["loop_closure_s"] = time.perf_counter() - start
    report("loop closure", 1.0)
    return PreparedDrives(
        tuple(p.chain for p in pieces), tuple(p.raw_poses for p in pieces), tuple(p.confidence for p in pieces),
        tuple(p.thumbs for p in pieces), keyframes, found, timings, stats, (db, params.images),
    )  # fmt: skip


def loop_inputs(
    pieces: Sequence[PreparedDrive], drives: Sequence[MappingDrive], params: MappingParams = MAPPING_DEFAULT
) -> tuple[tuple[NDArray[np.int64], ...], list[NDArray[np.float32]], list[F64]]:
    """Stage 2: per drive, the keyframes' positions, ``(K_d, h, w)`` thumbnails and ``(K_d,)`` times (s),
    the input of the loop-closure search (:func:`driftmap.core.loop_closure.search.detect_loops`)."""
    keyframes = tuple(_keyframes(p.raw_poses, params.keyframe_spacing_m) for p in pieces)
    key_thumbs = [p.thumbs[k] for p, k in zip(pieces, keyframes, strict=True)]
    key_times = [d.t_s[k] for d, k in zip(drives, keyframes, strict=True)]
    return keyframes, key_thumbs, key_times


def variant(params: MappingParams, *, loops: bool, groundings: bool) -> MappingParams:
    """``params`` with loop closures and groundings switched as the Table I variants need."""
    return replace(params, use_loop_closures=loops, use_groundings=groundings)
