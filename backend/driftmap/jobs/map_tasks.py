"""The map build as jobs: a ``map.build`` parent fans its stages out to subtasks any worker can take.

``map.build`` (args ``preset``) puts one ``map.drive`` job per segment of each mapping drive on the queue
(args ``drive_id``, ``first``/``stop`` (the segment's frames), ``preset``, ``offset``, ``total``; ``parent_id`` =
the build) and awaits them, running those still queued itself (work stealing, :mod:`driftmap.jobs.subtasks`).
A ``map.drive`` job stores its piece (visual odometry, thumbnails, frame statistics;
:func:`driftmap.services.map_drives.piece_bytes`) as a blob and its ``succeeded`` with the blob's hash in one
transaction. The parent joins each drive's segments, then searches loop closures in
``map.loops`` subtasks, one per block of query keyframes (:mod:`driftmap.jobs.loop_tasks`), and decides
them. The pose graph, topological map and new map version happen once, in the parent's final
transaction, which also keeps the pieces for the next build (:mod:`driftmap.services.map_pieces`: a
segment whose piece is kept gets no subtask; args ``full`` prepares every segment again and searches loop
closures afresh), starts the pose graph from the latest version's poses (not with ``full``) and keeps the
loop-closure search for the next build to resume (:mod:`driftmap.services.loop_searches`); the plan blob is
then dropped. A parent re-run (its worker died; the reaper re-queued it) reuses the subtasks already
finished; a subtask whose worker died is re-queued by the reaper of any live worker and taken by whoever is
free, the waiting parent included. Cancelling the parent cancels its subtasks; a failed subtask fails the
parent and the parent cancels the rest. The result is bit-identical to the one-process build.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.core.loop_closure.search import LoopMatch
from driftmap.core.mapping.drive import PreparedDrive, PreparedSegment
from driftmap.core.mapping.pipeline import (
    MappingDrive,
    MappingParams,
    build_segments,
    drive_segments,
    flat_offsets,
    join_drives,
    join_segments,
    prepare_segment,
)
from driftmap.errors import ConflictError, DriftmapError, NotFoundError
from driftmap.jobs.loop_tasks import FoundLoops, find_loops
from driftmap.jobs.presets import preset_params
from driftmap.jobs.runtime import JobContext
from driftmap.jobs.subtasks import (
    await_subtasks,
    drop_blobs,
    existing_subtasks,
    stop_subtasks,
    submit_subtasks,
)
from driftmap.services import jobs as job_service
from driftmap.services import kept_work, loop_searches, map_drives, map_pieces
from driftmap.services import maps as map_service
from driftmap.store.models import Drive, MapVersion, Site


def _site(ctx: JobContext, session: Session) -> Site:
    site = session.get(Site, ctx.job.site_id) if ctx.job.site_id is not None else None
    if site is None:
        raise NotFoundError(f"job {ctx.job.id}: site {ctx.job.site_id} does not exist (any more)")
    return site


def map_drive(ctx: JobContext) -> None:
    """Stage 1 of one segment of a drive of a build: its piece becomes a blob. Args: ``drive_id``,
    ``first``/``stop`` (the segment's frames), ``preset``, ``offset``/``total`` (flat index of the drive's
    first frame, frames of all the build's drives)."""
    _preset_name, params = preset_params(ctx.args)
    flat = (int(ctx.args["offset"]), int(ctx.args["total"]))
    span = (int(ctx.args["first"]), int(ctx.args["stop"]))
    storage = ctx.runtime.storage
    ctx.report("odometry", 0.0)
    with storage.db.session() as session:
        drive = session.get(Drive, int(ctx.args["drive_id"]))
        if drive is None:
            raise NotFoundError(f"job {ctx.job.id}: drive {ctx.args['drive_id']} does not exist (any more)")
        loaded = map_drives.load_mapping_drive(session, storage.blobs, drive)
    piece = prepare_segment(loaded.input, params, flat, span, ctx.report)
    data = map_drives.piece_bytes(piece)
    with storage.blobs.batch() as batch, storage.db.session() as session:
        result = {
            "drive_id": drive.id,
            "piece_key": str(ctx.args.get("piece_key", "")),
            "first": span[0],
            "stop": span[1],
            "piece_sha256": batch.put(data),
            "frames": span[1] - span[0],
            "seconds": piece.seconds,
        }
        ctx.succeed(session, result)


def _segment_subtasks(
    ctx: JobContext,
    drives: list[tuple[int, int]],
    preset: str,
    params: MappingParams,
    keys: list[str],
    kept: dict[str, str],
) -> list[int]:
    """Ids of this build's ``map.drive`` jobs, one per segment of each (drive id, frames) whose piece key
    (``keys``, in segment order) is not ``kept``, submitted unless they exist."""
    total, offsets = sum(n for _d, n in drives), np.cumsum([0] + [n for _d, n in drives]).tolist()
    spans = [
        (k, drive_id, first, stop)
        for k, (drive_id, n) in enumerate(drives)
        for first, stop in drive_segments(n, params.segment_frames)
    ]
    args = [
        {
            "drive_id": drive_id,
            "first": first,
            "stop": stop,
            "preset": preset,
            "offset": offsets[k],
            "total": total,
            "piece_key": key,
        }
        for (k, drive_id, first, stop), key in zip(spans, keys, strict=True)
        if key not in kept
    ]
    earlier = existing_subtasks(ctx, "map.drive")
    if earlier:
        key = ("drive_id", "first", "stop")
        if [[a[k] for k in key] for _i, a in earlier] != [[a[k] for k in key] for a in args]:
            raise ConflictError("the site's mapping drives changed while its map was being built")
        return [i for i, _a in earlier]
    return submit_subtasks(ctx, "map.drive", args) if args else []


def map_build(ctx: JobContext) -> None:
    """Build the next map version of the job's site, the odometry of segments no earlier build kept in
    ``map.drive`` subtasks. Args: ``preset``; ``full`` (bool): prepare every segment again."""
    preset, params = preset_params(ctx.args)
    full = bool(ctx.args.get("full", False))
    label = f"{ctx.job.created_by or 'api'} via job {ctx.job.id}"
    storage = ctx.runtime.storage
    ctx.report("loading drives", 0.0)
    with storage.db.session() as session:
        site = _site(ctx, session)
        site_id = site.id
        version = session.scalar(
            select(MapVersion).where(MapVersion.site_id == site.id, MapVersion.created_by == label)
        )
        if version is None:  # the normal case; a version of this job exists only if it already succeeded
            map_service.ensure_buildable(session, site)
            loaded = map_service.load_site_drives(session, storage.blobs, site)
            drives = [(d.id, d.frame_count) for d in loaded.drives]
            keys = map_pieces.segment_keys([d for d, _n in drives], loaded.contents, loaded.inputs, params)
            kept = {} if full else map_pieces.kept_pieces(session, storage.blobs, keys)
    if version is not None:
        with storage.db.session() as session:
            ctx.succeed(session, _result(version))
        return
    try:
        ids = _segment_subtasks(ctx, drives, preset, params, keys, kept)
        start = time.monotonic()
        results = await_subtasks(ctx, ids, "odometry", map_drive)
        shas = kept | {str(r["piece_key"]): str(r["piece_sha256"]) for r in results}
        with storage.db.session() as session:
            inputs = _site_drives(ctx, session, drives).inputs
        pieces = _pieces(ctx, [shas[k] for k in keys], params, inputs)
        odometry_s = time.monotonic() - start
        loops: tuple[tuple[LoopMatch, ...], float] | None = None
        chains = loop_searches.chain_keys(keys, inputs, params)
        search: FoundLoops | None = None
        if params.use_loop_closures:
            closures, loop_s, search = find_loops(ctx, site_id, pieces, inputs, params, chains, full)
            loops = (closures, loop_s)
    except (DriftmapError, job_service.JobCancelled):
        stop_subtasks(ctx)
        raise
    segments = [
        (drives[k][0], span, key, shas[key])
        for (k, span), key in zip(build_segments(inputs, params), keys, strict=True)
    ]
    with storage.blobs.batch() as batch, storage.db.session() as session:
        site = _site(ctx, session)
        loaded = _site_drives(ctx, session, drives)
        prepared = join_drives(pieces, loaded.inputs, params, ctx.report, odometry_s, loops)
        found = None if search is None else (search.plan, search.scored)
        work = kept_work.KeptWork(chains, [d for d, _n in drives], segments, len(keys) - len(ids), found)
        build, dropped = kept_work.solve_and_keep(
            session, storage.blobs, batch, site, loaded.inputs, prepared, params, work, ctx.report, full
        )
        version = map_service.store_map_version(session, batch, site, loaded, build, params, label)
        ctx.succeed(session, _result(version))  # no progress report from here: this transaction writes
    if search is not None and search.plan_sha256 is not None:
        drop_blobs(ctx, [search.plan_sha256])
    map_pieces.drop_stale(storage, dropped)


def _site_drives(ctx: JobContext, session: Session, drives: list[tuple[int, int]]) -> map_service.SiteDrives:
    """The site's mapping drives as loaded for the pipeline; they must be those the build started with.

    Raises:
        ConflictError: a mapping drive was added or deleted during the build.
    """
    loaded = map_service.load_site_drives(session, ctx.runtime.storage.blobs, _site(ctx, session))
    if [d.id for d in loaded.drives] != [d for d, _n in drives]:
        raise ConflictError("the site's mapping drives changed while its map was being built")
    return loaded


def _result(version: MapVersion) -> dict[str, Any]:
    return {
        "map_version_id": version.id,
        "version": version.version,
        "stats": map_service.json_safe(version.stats),
    }


def _pieces(
    ctx: JobContext, shas: list[str], params: MappingParams, drives: list[MappingDrive]
) -> list[PreparedDrive]:
    """Each drive's piece, joined from its segments' blobs (``shas`` in segment order), kept ones given this
    build's frame sample (:func:`driftmap.services.map_drives.piece_from_bytes`)."""
    flats = flat_offsets(drives)
    segments: list[list[PreparedSegment]] = [[] for _d in drives]
    for sha, (k, (first, _stop)) in zip(shas, build_segments(drives, params), strict=True):
        if not ctx.runtime.storage.blobs.exists(sha):
            raise NotFoundError(
                f"job {ctx.job.id}: the odometry of drive {drives[k].name!r} (blob {sha}) is gone"
            )
        flat = (flats[k][0] + first, flats[k][1])
        data = ctx.runtime.storage.blobs.get(sha)
        segments[k].append(map_drives.piece_from_bytes(data, params, flat, drives[k]))
    return [join_segments(d, s, params) for d, s in zip(drives, segments, strict=True)]
