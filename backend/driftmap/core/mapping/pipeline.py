"""The Semi-Supervised SLAM mapping pipeline ([SSLAM], III-A): odometry, loops, groundings, graph, map.

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
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import NDArray

from driftmap.core.graph import posegraph
from driftmap.core.graph.constraints import GroundingConstraint, LoopConstraint
from driftmap.core.graph.drive_bias import NO_BIAS, solve_with_calibration
from driftmap.core.mapping.prepare import (
    MAP_PRESETS,
    MAPPING_DEFAULT,
    MAPPING_FAST,
    MAPPING_PAPER,
    MappingDrive,
    MappingParams,
    PreparedDrives,
    build_segments,
    drive_segments,
    flat_offsets,
    join_drives,
    join_segments,
    prepare_drives,
    prepare_segment,
    restride_segment,
    variant,
)
from driftmap.core.sesame.salient_database import PairScores
from driftmap.core.topomap.build import build_topomap
from driftmap.core.topomap.database import database_selector, frame_stats
from driftmap.core.topomap.model import TopoMap
from driftmap.core.types import F64, ProgressFn

__all__ = [
    "MAPPING_DEFAULT",
    "MAPPING_FAST",
    "MAPPING_PAPER",
    "MAP_PRESETS",
    "ClosureRecord",
    "GroundingResidual",
    "MapBuild",
    "MappingDrive",
    "MappingParams",
    "PreparedDrives",
    "build_map",
    "build_segments",
    "drive_segments",
    "flat_offsets",
    "join_drives",
    "join_segments",
    "prepare_drives",
    "prepare_segment",
    "restride_segment",
    "solve_map",
    "variant",
]


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
        holistic_ptr: (M + 1,) int64 node offsets of [SSLAM]'s plain selection (the topomap's default
            selector), kept for holistic-SAD localisation when the SESAME database chose ``topomap.chosen``.
        holistic_thumbs: (S', h, w) float32 thumbnails of that plain selection, node by node.
        database_scores: the SESAME database's pair scores this build used (flat frame indices), for the
            next build of the same drives (None when SESAME is off).
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
    database_scores: PairScores | None = None


def solve_map(
    prepared: PreparedDrives,
    drives: Sequence[MappingDrive],
    params: MappingParams = MAPPING_DEFAULT,
    progress: ProgressFn | None = None,
    database_scores: PairScores | None = None,
) -> MapBuild:
    """Stages 4-5: the pose graph (with the closures and groundings the params allow) and the map.

    Drives that get no grounding (groundings off, or none recorded) start from their ``start_wT``
    when given; otherwise the pose graph places them through closures or anchors them weakly. The graph
    always starts cold, so the map depends on the drives and groundings only, never on earlier builds (an
    earlier solution as the starting point reached a nearby minimum up to 7.6 m away on the 20 km site).
    ``database_scores`` holds SESAME
    database pair scores an earlier build of these drives computed (flat frame indices): the pairs it knows
    are not scored again; the build returns the pairs it used in ``MapBuild.database_scores``.
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
        LoopConstraint(
            a=(c.chain_a, int(keyframes[c.chain_a][c.idx_a])),
            b=(c.chain_b, int(keyframes[c.chain_b][c.idx_b])),
            sigmas=(c.sigma_xy_m, c.sigma_xy_m, c.sigma_theta_rad),
            sad=c.d,
        )
        for c in (prepared.closures if params.use_loop_closures else ())
    ]
    groundings = [
        GroundingConstraint(frame=(k, int(i)), xy_m=(float(x), float(y)), sigma_m=params.grounding_sigma_m)
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
    scores = (database_scores or PairScores()) if params.database.use_sesame else None
    topomap, database_stats, plain = _topomap_with_database(graph.wTi, prepared, drives, params, scores)
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
        "graph_iterations": graph.iterations,
        "graph_nodes": graph.num_nodes,
        "calibrated_drives": sum(b != NO_BIAS for b in biases),
        "max_scale_error": max(abs(b.scale - 1.0) for b in biases),
        "max_heading_rate_deg_per_100m": max(abs(np.degrees(b.yaw_rate_rad_per_m)) * 100.0 for b in biases),
        "max_turn_gain_error": max(abs(b.turn_gain - 1.0) for b in biases),
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
        reference_thumbs=_flat_rows(prepared.thumbs, topomap.chosen),
        holistic_ptr=None if plain is None else plain.chosen_ptr,
        holistic_thumbs=None if plain is None else _flat_rows(prepared.thumbs, plain.chosen),
        database_scores=scores,
    )


def _flat_rows(per_drive: Sequence[NDArray[np.float32]], flat: NDArray[np.int64]) -> NDArray[np.float32]:
    """``(S, h, w)`` rows ``flat`` (flat frame indices over the drives in order) of per-drive ``(N_d, h, w)``
    arrays, without joining them (the mapping frames' thumbnails of a large site are gigabytes)."""
    ptr = np.r_[0, np.cumsum([a.shape[0] for a in per_drive])].astype(np.int64)
    drive = np.searchsorted(ptr, flat, side="right") - 1
    out = np.empty((flat.size, *per_drive[0].shape[1:]), dtype=np.float32)
    for k in np.unique(drive).tolist():
        at = drive == k
        out[at] = per_drive[k][flat[at] - ptr[k]]
    return out


def _topomap_with_database(
    wTi: Sequence[F64],
    prepared: PreparedDrives,
    drives: Sequence[MappingDrive],
    params: MappingParams,
    scores: PairScores | None,
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
    thumbs = np.concatenate(prepared.thumbs)
    select = database_selector(stats, thumbs, chain_ptr, db, params.loops.sad, scores)
    per_node = max(params.topomap.frames_per_node, db.frames_per_node if db.use_sesame else 0)
    topo_params = replace(params.topomap, frames_per_node=per_node)
    topomap = build_topomap(
        list(wTi), quality=list(prepared.confidence), params=topo_params, select_frames=select
    )
    figures: dict[str, float | int] = {
        "reference_frames": int(topomap.chosen.size),
        "quality_rejected_fraction": stats.rejected_fraction,
    }
    if scores is not None:
        figures["database_pairs_reused"], figures["database_pairs_scored"] = scores.reused, scores.scored
    if stats.classifier is not None:
        figures["quality_holdout_accuracy"] = stats.classifier.holdout_accuracy
    return topomap, figures, plain


def build_map(
    drives: Sequence[MappingDrive],
    params: MappingParams = MAPPING_DEFAULT,
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
