"""The Semi-Supervised SLAM mapping pipeline (paper 000, III-A): odometry, loops, groundings, graph, map.

One pure function, :func:`build_map`, turns a site's mapping drives into an optimised, compressed map. The
CLI, the workers and the tests call it the same way; frames arrive through a callable per drive so that
storage stays outside the core. Poses are ``[x_m, y_m, yaw_rad]`` in the survey frame (x east, y north,
yaw counter-clockwise from +x, the vehicle heading) of the floor point under the camera.

Stages: (1) ground-plane visual odometry of every drive, each frame also down-sampled and
patch-normalised for place recognition; (2) keyframes every ``keyframe_spacing_m`` of odometry travel;
(3) loop closures between keyframes; (4) a GTSAM pose graph of every drive with robust closures and
grounding factors; (5) the topological map.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from driftmap.core import loops as loop_search
from driftmap.core import posegraph
from driftmap.core.camera import CameraModel
from driftmap.core.images import preprocess
from driftmap.core.odometry import dead_reckon
from driftmap.core.odometry_calibration import NO_BIAS, solve_with_calibration
from driftmap.core.params import IMAGES_DEFAULT, ODOMETRY_DEFAULT, ODOMETRY_FAST, ImageParams, OdometryParams
from driftmap.core.place_database import (
    DATABASE_DEFAULT,
    DatabaseParams,
    FrameStats,
    FrameStatsPass,
    database_selector,
    finish_frame_stats,
    frame_stats,
)
from driftmap.core.topomap import PAPER as TOPO_PAPER
from driftmap.core.topomap import TopoMap, TopoMapParams, build_topomap

ProgressFn = Callable[[str, float], None]
F64 = NDArray[np.float64]


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
    """

    name: str
    camera: CameraModel
    t_s: F64
    frames: Callable[[], Iterable[NDArray[np.uint8]]]
    groundings: Sequence[tuple[int, float, float]] = ()
    start_wT: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class MappingParams:
    """Every knob of a map build; presets below."""

    odometry: OdometryParams = ODOMETRY_DEFAULT  # ground-plane VO (eq. 1, 2)
    images: ImageParams = IMAGES_DEFAULT  # place-recognition pre-processing (IV-C)
    loops: loop_search.LoopParams = loop_search.LOOPS_DEFAULT  # loop-closure search (eq. 3)
    graph: posegraph.PoseGraphParams = posegraph.ROBUST  # pose-graph back end
    topomap: TopoMapParams = TOPO_PAPER  # map compression (III-A-4)
    database: DatabaseParams = DATABASE_DEFAULT  # each node's reference frames: SESAME + quality filter
    keyframe_spacing_m: float = 1.0  # odometry travel between keyframes used for loop closure, metres
    grounding_sigma_m: float = 0.5  # surveyor click accuracy, metres
    use_loop_closures: bool = True  # Table I variants switch these two off
    use_groundings: bool = True
    calibration_rounds: int = 5  # most odometry self-calibration passes (scale, heading rate)
    calibration_window_m: float = 15.0  # travel per window when fitting the calibration, metres


PAPER = MappingParams()
FAST = MappingParams(odometry=ODOMETRY_FAST, loops=loop_search.LOOPS_FAST, keyframe_spacing_m=2.0)


@dataclass(frozen=True)
class ClosureRecord:
    """A loop closure of a build: keyframes by (drive, frame position), its score and fate."""

    drive_a: int
    frame_a: int
    drive_b: int
    frame_b: int
    d_score: float
    accepted: bool
    chi2: float


@dataclass(frozen=True)
class GroundingResidual:
    """Optimised minus surveyed position of one grounded frame, metres."""

    drive: int
    frame: int
    surveyed_xy_m: tuple[float, float]
    dx_m: float
    dy_m: float
    distance_m: float


@dataclass(frozen=True, eq=False)
class MapBuild:
    """The result of :func:`build_map`.

    Attributes:
        wTi: per drive, (N_d, 3) optimised poses.
        dead_reckoned: per drive, (N_d, 3) odometry-only poses (aligned to groundings or to start_wT).
        keyframes: per drive, the frame positions used for loop closure.
        closures: every loop closure found, with whether the optimiser kept it.
        residuals: one per grounding used.
        topomap: the compressed map.
        odometry_confidence: per drive, (N_d,) confidence of the step into each frame (1 for frame 0).
        stats: figures of the build (counts, errors, seconds per stage).
        reference_thumbs: (S, h, w) float32 thumbnails of ``topomap.chosen``, the localiser's references.
        holistic_ptr: (M + 1,) int64 node offsets of paper 000's plain selection (the topomap's default
            selector), kept for holistic-SAD localisation when the SESAME database chose ``topomap.chosen``.
        holistic_thumbs: (S', h, w) float32 thumbnails of that plain selection, node by node.
    """

    wTi: tuple[F64, ...]
    dead_reckoned: tuple[F64, ...]
    keyframes: tuple[NDArray[np.int64], ...]
    closures: tuple[ClosureRecord, ...]
    residuals: tuple[GroundingResidual, ...]
    topomap: TopoMap
    odometry_confidence: tuple[F64, ...]
    stats: dict[str, float | int] = field(default_factory=dict)
    reference_thumbs: NDArray[np.float32] | None = None
    holistic_ptr: NDArray[np.int64] | None = None
    holistic_thumbs: NDArray[np.float32] | None = None


def _keyframes(wTi: F64, spacing_m: float) -> NDArray[np.int64]:
    """Frame positions at every ``spacing_m`` of travelled path (frame 0 always)."""
    steps = np.linalg.norm(np.diff(wTi[:, :2], axis=0), axis=1)
    travelled = np.concatenate([[0.0], np.cumsum(steps)])
    slot = np.floor(travelled / spacing_m).astype(np.int64)
    return np.flatnonzero(np.concatenate([[True], slot[1:] != slot[:-1]])).astype(np.int64)


class _Tee:
    """Yields frames to odometry while keeping their place-recognition thumbnails and feeding the
    database's frame statistics (when given), so each frame is decoded once."""

    def __init__(
        self, frames: Iterable[NDArray[np.uint8]], params: ImageParams, stats: FrameStatsPass | None = None
    ) -> None:
        self._frames = frames
        self._params = params
        self.stats = stats
        self.thumbs: list[NDArray[np.float32]] = []

    def __iter__(self) -> Iterator[NDArray[np.uint8]]:
        for frame in self._frames:
            self.thumbs.append(preprocess(frame, self._params))
            if self.stats is not None:
                self.stats.add(frame)
            yield frame


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

    chains: tuple[posegraph.OdometryChain, ...]
    raw_poses: tuple[F64, ...]
    confidence: tuple[F64, ...]
    thumbs: tuple[NDArray[np.float32], ...]
    keyframes: tuple[NDArray[np.int64], ...]
    closures: tuple[loop_search.LoopClosure, ...]
    timings: dict[str, float]
    frame_stats: FrameStats | None = None
    frame_stats_params: tuple[DatabaseParams, ImageParams] | None = None


def prepare_drives(
    drives: Sequence[MappingDrive],
    params: MappingParams = PAPER,
    progress: ProgressFn | None = None,
    workers: int = 1,
) -> PreparedDrives:
    """Stages 1-3: visual odometry and thumbnails of every frame, keyframes, loop-closure search.

    Args:
        drives: every mapping drive of the site.
        params: pipeline parameters (``use_loop_closures`` off skips the search).
        progress: called with (stage name, fraction 0..1 of that stage), from the calling thread.
        workers: drives dead-reckoned at once in threads (OpenCV and NumPy release the GIL in their
            inner loops, so two threads use two cores).

    Raises:
        ValueError: no drive, or a drive whose frame count disagrees with its times.
    """
    if not drives:
        raise ValueError("a map build needs at least one mapping drive")
    report = progress or (lambda _stage, _fraction: None)
    timings: dict[str, float] = {}
    start = time.perf_counter()
    report("odometry", 0.0)
    counts = [int(d.t_s.shape[0]) for d in drives]
    offsets = np.r_[0, np.cumsum(counts)].astype(int)
    db = params.database
    passes = [
        FrameStatsPass(int(offsets[k]), int(offsets[-1]), db, params.images) if db.enabled else None
        for k in range(len(drives))
    ]
    with ThreadPoolExecutor(max(1, min(workers, len(drives)))) as pool:
        futures = [pool.submit(_drive_odometry, d, params, p) for d, p in zip(drives, passes, strict=True)]
        for done, _ in enumerate(as_completed(futures), start=1):
            report("odometry", done / len(drives))
        results = [f.result() for f in futures]
    chains = [r[0] for r in results]
    raw_poses = [r[1] for r in results]
    confidence = [r[2] for r in results]
    thumbs = [r[3] for r in results]
    timings["odometry_s"] = time.perf_counter() - start

    stats = None
    if db.enabled:  # the classifier of the database's quality filter, from the frames seen above
        start = time.perf_counter()
        stats = finish_frame_stats([p for p in passes if p is not None], counts, db, params.images)
        timings["frame_stats_s"] = time.perf_counter() - start

    start = time.perf_counter()
    keyframes = tuple(_keyframes(p, params.keyframe_spacing_m) for p in raw_poses)
    found: tuple[loop_search.LoopClosure, ...] = ()
    if params.use_loop_closures:
        report("loop closure", 0.0)
        key_thumbs = [t[k] for t, k in zip(thumbs, keyframes, strict=True)]
        key_times = [d.t_s[k] for d, k in zip(drives, keyframes, strict=True)]
        found = tuple(loop_search.detect_loops(key_thumbs, params.loops, key_times).closures)
    report("loop closure", 1.0)
    timings["loop_closure_s"] = time.perf_counter() - start
    return PreparedDrives(
        tuple(chains), tuple(raw_poses), tuple(confidence), tuple(thumbs), keyframes, found, timings,
        stats, (db, params.images),
    )  # fmt: skip


def _drive_odometry(
    drive: MappingDrive, params: MappingParams, stats: FrameStatsPass | None = None
) -> tuple[posegraph.OdometryChain, F64, F64, NDArray[np.float32]]:
    """Dead reckoning of one drive: its odometry chain, (N, 3) poses, (N,) confidence, (N, h, w) thumbnails.

    ``stats``, when given, takes every frame of the drive and is closed at the end.
    """
    tee = _Tee(drive.frames(), params.images, stats)
    reckoning = dead_reckon(tee, drive.camera, params.odometry, drive.start_wT or (0.0, 0.0, 0.0))
    if len(tee.thumbs) != drive.t_s.shape[0]:
        raise ValueError(f"drive {drive.name!r}: {len(tee.thumbs)} frames, but {drive.t_s.shape[0]} times")
    if stats is not None:
        stats.close()
    steps = reckoning.steps
    iTj = np.array([s.prev_T_curr for s in steps], dtype=np.float64).reshape(-1, 3)
    sigmas = np.array([[s.sigma_xy_m, s.sigma_xy_m, s.sigma_theta_rad] for s in steps]).reshape(-1, 3)
    confidence = np.concatenate([[1.0], [s.confidence for s in steps]])
    return posegraph.OdometryChain(iTj, sigmas), reckoning.wTi, confidence, np.stack(tee.thumbs)


def solve_map(
    prepared: PreparedDrives,
    drives: Sequence[MappingDrive],
    params: MappingParams = PAPER,
    progress: ProgressFn | None = None,
) -> MapBuild:
    """Stages 4-5: the pose graph (with the closures and groundings the params allow) and the map.

    Drives that get no grounding (groundings off, or none recorded) start from their ``start_wT``
    when given; otherwise the pose graph places them through closures or anchors them weakly.
    """
    report = progress or (lambda _stage, _fraction: None)
    timings = dict(prepared.timings)
    start = time.perf_counter()
    report("pose graph", 0.0)
    chains = []
    for chain, poses, drive in zip(prepared.chains, prepared.raw_poses, drives, strict=True):
        free = drive.start_wT is not None and not (params.use_groundings and drive.groundings)
        chains.append(replace(chain, wTi_init=poses) if free else chain)
    keyframes = prepared.keyframes
    closures = [
        posegraph.LoopClosure(
            a=(c.chain_a, int(keyframes[c.chain_a][c.idx_a])),
            b=(c.chain_b, int(keyframes[c.chain_b][c.idx_b])),
            sigmas=(c.sigma_xy_m, c.sigma_xy_m, c.sigma_theta_rad),
            sad=c.d,
        )
        for c in (prepared.closures if params.use_loop_closures else ())
    ]
    groundings = [
        posegraph.Grounding(frame=(k, int(i)), xy_m=(float(x), float(y)), sigma_m=params.grounding_sigma_m)
        for k, drive in enumerate(drives)
        if params.use_groundings
        for i, x, y in drive.groundings
    ]
    graph = posegraph.optimise_pose_graph(chains, closures, groundings, params.graph)
    graph, biases = solve_with_calibration(
        graph,
        chains,
        closures,
        groundings,
        params.graph,
        params.calibration_rounds,
        params.calibration_window_m,
    )
    report("pose graph", 1.0)
    timings["pose_graph_s"] = time.perf_counter() - start

    start = time.perf_counter()
    report("topological map", 0.0)
    topomap, database_stats, plain = _topomap_with_database(graph.wTi, prepared, drives, params)
    report("topological map", 1.0)
    timings["topomap_s"] = time.perf_counter() - start

    closure_records = tuple(
        ClosureRecord(c.a[0], c.a[1], c.b[0], c.b[1], float(c.sad), bool(ok), float(x2))
        for c, ok, x2 in zip(closures, graph.closure_accepted, graph.closure_chi2, strict=True)
    )
    residuals = tuple(
        GroundingResidual(g.frame[0], g.frame[1], g.xy_m, float(r[0]), float(r[1]), float(r[2]))
        for g, r in zip(groundings, graph.grounding_residual_m, strict=True)
    )
    stats: dict[str, float | int] = {
        "drives": len(drives),
        "frames": int(sum(p.shape[0] for p in prepared.raw_poses)),
        "keyframes": int(sum(k.shape[0] for k in keyframes)),
        "closures_found": len(closure_records),
        "closures_accepted": int(sum(c.accepted for c in closure_records)),
        "groundings": len(residuals),
        "nodes": topomap.n_nodes,
        "graph_initial_error": graph.initial_error,
        "graph_final_error": graph.final_error,
        "calibrated_drives": sum(b != NO_BIAS for b in biases),
        "max_scale_error": max(abs(b.scale - 1.0) for b in biases),
        "max_heading_rate_deg_per_100m": max(abs(np.degrees(b.yaw_rate_rad_per_m)) * 100.0 for b in biases),
        **database_stats,
        **timings,
    }
    return MapBuild(
        wTi=tuple(graph.wTi),
        dead_reckoned=_aligned_dead_reckoning(prepared.raw_poses, graph.wTi, drives, params),
        keyframes=keyframes,
        closures=closure_records,
        residuals=residuals,
        topomap=topomap,
        odometry_confidence=prepared.confidence,
        stats=stats,
        reference_thumbs=np.concatenate(prepared.thumbs)[topomap.chosen],
        holistic_ptr=None if plain is None else plain.chosen_ptr,
        holistic_thumbs=None if plain is None else np.concatenate(prepared.thumbs)[plain.chosen],
    )


def _topomap_with_database(
    wTi: Sequence[F64], prepared: PreparedDrives, drives: Sequence[MappingDrive], params: MappingParams
) -> tuple[TopoMap, dict[str, float | int], TopoMap | None]:
    """Stage 5: the topological map, each node's frames chosen by the SESAME database when it is on.

    Returns the map, figures of the database, and (database on) the map with the plain default selection.
    """
    db = params.database
    plain = build_topomap(list(wTi), quality=list(prepared.confidence), params=params.topomap)
    if not db.enabled:
        return plain, {"reference_frames": int(plain.chosen.size)}, None
    counts = [t.shape[0] for t in prepared.thumbs]
    stats = prepared.frame_stats
    if stats is None or prepared.frame_stats_params != (db, params.images):
        stats = frame_stats([d.frames for d in drives], counts, db, params.images)
    chain_ptr = np.r_[0, np.cumsum(counts)].astype(np.int64)
    select = database_selector(stats, np.concatenate(prepared.thumbs), chain_ptr, db, params.loops.sad)
    per_node = max(params.topomap.frames_per_node, db.frames_per_node if db.use_sesame else 0)
    topo_params = replace(params.topomap, frames_per_node=per_node)
    topomap = build_topomap(
        list(wTi), quality=list(prepared.confidence), params=topo_params, select_frames=select
    )
    figures: dict[str, float | int] = {
        "reference_frames": int(topomap.chosen.size),
        "quality_rejected_fraction": stats.rejected_fraction,
    }
    if stats.classifier is not None:
        figures["quality_holdout_accuracy"] = stats.classifier.holdout_accuracy
    return topomap, figures, plain


def build_map(
    drives: Sequence[MappingDrive],
    params: MappingParams = PAPER,
    progress: ProgressFn | None = None,
    workers: int = 1,
) -> MapBuild:
    """Build the map of a site from its mapping drives: :func:`prepare_drives` then :func:`solve_map`.

    Args:
        drives: every mapping drive, each with its frames, times and groundings.
        params: pipeline parameters; ``use_loop_closures``/``use_groundings`` select Table I variants.
        progress: called with (stage name, fraction 0..1 of that stage).
        workers: drives dead-reckoned at once (see :func:`prepare_drives`).

    Returns:
        :class:`MapBuild` with optimised poses, closures, residuals and the topological map.
    """
    return solve_map(prepare_drives(drives, params, progress, workers), drives, params, progress)


def _aligned_dead_reckoning(
    raw: Sequence[F64], optimised: Sequence[F64], drives: Sequence[MappingDrive], params: MappingParams
) -> tuple[F64, ...]:
    """Odometry-only trajectories placed like the optimised ones at their first frame (for reports)."""
    out = []
    for poses, opt, drive in zip(raw, optimised, drives, strict=True):
        if drive.start_wT is not None and not (params.use_groundings and drive.groundings):
            out.append(poses)
            continue
        c0, s0 = np.cos(poses[0, 2]), np.sin(poses[0, 2])
        rel = poses[:, :2] - poses[0, :2]
        local = np.stack([c0 * rel[:, 0] + s0 * rel[:, 1], -s0 * rel[:, 0] + c0 * rel[:, 1]], axis=1)
        c1, s1 = np.cos(opt[0, 2]), np.sin(opt[0, 2])
        xy = opt[0, :2] + np.stack(
            [c1 * local[:, 0] - s1 * local[:, 1], s1 * local[:, 0] + c1 * local[:, 1]], axis=1
        )
        yaw = opt[0, 2] + (poses[:, 2] - poses[0, 2])
        out.append(np.column_stack([xy, np.arctan2(np.sin(yaw), np.cos(yaw))]))
    return tuple(out)


def variant(params: MappingParams, *, loops: bool, groundings: bool) -> MappingParams:
    """``params`` with loop closures and groundings switched as the Table I variants need."""
    return replace(params, use_loop_closures=loops, use_groundings=groundings)
