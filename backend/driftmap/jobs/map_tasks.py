"""The map build as jobs: a ``map.build`` parent fans its drives' odometry out to ``map.drive`` subtasks.

``map.build`` (args ``preset``) puts one ``map.drive`` job per mapping drive on the queue (args ``drive_id``,
``preset``, ``offset``, ``total``; ``parent_id`` = the build), then *work-steals*: it claims and runs, in its
own thread, any of its subtasks still queued, and otherwise waits (polling, reporting progress, so a cancel
reaches it) for those other workers took. One worker therefore builds alone without deadlock, and every
further worker takes drives off the queue. A ``map.drive`` job stores its piece (visual odometry, thumbnails,
frame statistics; :func:`driftmap.services.map_drives.piece_bytes`) as a blob and its ``succeeded`` with the
blob's hash in one transaction. The join -- frame statistics, keyframes, loop closure, pose graph,
topological map -- and the new map version happen once, in the parent's final transaction; the pieces' blobs
are then dropped. A parent re-run (its worker died; the reaper re-queued it) reuses the subtasks already
finished; a subtask whose worker died is re-queued by the reaper of any live worker and taken by whoever
is free, the waiting parent included. Cancelling the parent cancels its subtasks; a failed subtask fails
the parent and the parent cancels the rest. The result is bit-identical to the one-process build.
"""

from __future__ import annotations

import contextlib
import logging
import time
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.core.drive_prep import PreparedDrive
from driftmap.core.mapping import FAST, PAPER, MappingParams, join_drives, prepare_drive, solve_map
from driftmap.errors import BadInputError, ConflictError, DriftmapError, NotFoundError
from driftmap.jobs.runtime import JobContext, TaskFn, run_job
from driftmap.services import jobs as job_service
from driftmap.services import map_drives
from driftmap.services import maps as map_service
from driftmap.store.job_models import Job
from driftmap.store.models import Drive, MapVersion, Site

log = logging.getLogger(__name__)

MAP_PRESETS: dict[str, MappingParams] = {"paper": PAPER, "fast": FAST}
POLL_S = 0.5
"""How often a waiting ``map.build`` looks at its subtasks, seconds."""


def _preset(args: dict[str, Any]) -> tuple[str, MappingParams]:
    preset = str(args.get("preset", "paper"))
    if preset not in MAP_PRESETS:
        raise BadInputError(f"unknown preset {preset!r}; one of {', '.join(MAP_PRESETS)}", field="preset")
    return preset, MAP_PRESETS[preset]


def _site(ctx: JobContext, session: Session) -> Site:
    site = session.get(Site, ctx.job.site_id) if ctx.job.site_id is not None else None
    if site is None:
        raise NotFoundError(f"job {ctx.job.id}: site {ctx.job.site_id} does not exist (any more)")
    return site


def map_drive(ctx: JobContext) -> None:
    """Stage 1 of one drive of a build: its piece becomes a blob. Args: ``drive_id``, ``preset``,
    ``offset``/``total`` (flat index of its first frame, frames of all the build's drives)."""
    _preset_name, params = _preset(ctx.args)
    flat = (int(ctx.args["offset"]), int(ctx.args["total"]))
    storage = ctx.runtime.storage
    ctx.report("odometry", 0.0)
    with storage.db.session() as session:
        drive = session.get(Drive, int(ctx.args["drive_id"]))
        if drive is None:
            raise NotFoundError(f"job {ctx.job.id}: drive {ctx.args['drive_id']} does not exist (any more)")
        loaded = map_drives.load_mapping_drive(session, storage.blobs, drive)
    piece = prepare_drive(loaded.input, params, flat, lambda f: ctx.report("odometry", f))
    data = map_drives.piece_bytes(piece)
    with storage.blobs.batch() as batch, storage.db.session() as session:
        result = {
            "drive_id": drive.id,
            "piece_sha256": batch.put(data),
            "frames": piece.n_frames,
            "seconds": piece.seconds,
        }
        ctx.succeed(session, result)


def _subtasks(ctx: JobContext, drives: list[tuple[int, int]], preset: str) -> list[int]:
    """Ids of this build's ``map.drive`` jobs, one per (drive id, frames), submitted unless they exist."""
    total = sum(n for _d, n in drives)
    with ctx.runtime.storage.db.session() as session:
        existing = job_service.children(session, ctx.job.id)
        if existing:
            if [int(j.args["drive_id"]) for j in existing] != [d for d, _n in drives]:
                raise ConflictError("the site's mapping drives changed while its map was being built")
            return [j.id for j in existing]
        ids, offset = [], 0
        for drive_id, n in drives:
            args = {"drive_id": drive_id, "preset": preset, "offset": offset, "total": total}
            job = job_service.submit(
                session, ctx.enqueue, "map.drive", args, site_id=ctx.job.site_id,
                created_by=ctx.job.created_by, parent_id=ctx.job.id,
            )  # fmt: skip
            ids.append(job.id)
            offset += n
    return ids


def _await_subtasks(ctx: JobContext, ids: list[int]) -> list[dict[str, Any]]:
    """Run this build's queued subtasks here, wait for those running elsewhere; their results in order.

    Raises:
        DriftmapError: a subtask failed (its error is named).
        JobCancelled: a subtask was cancelled.
    """
    while True:
        with ctx.runtime.storage.db.session() as session:
            rows = {
                j.id: (j.status, j.error, j.result, j.progress)
                for j in job_service.children(session, ctx.job.id)
            }
        states = [rows[i] for i in ids]
        failed = [(i, s[1]) for i, s in zip(ids, states, strict=True) if s[0] == "failed"]
        if failed:
            raise DriftmapError(f"drive subtask {failed[0][0]} failed: {failed[0][1]}")
        if any(s[0] == "cancelled" for s in states):
            raise job_service.JobCancelled(f"job {ctx.job.id}: a drive subtask was cancelled")
        done = sum(s[0] == "succeeded" for s in states)
        if done == len(ids):
            return [dict(s[2] or {}) for s in states]
        running = sum(s[3] for s in states if s[0] == "running")
        ctx.report("odometry", (done + running) / len(ids))  # also: a cancel of the build stops it here
        queued = [i for i, s in zip(ids, states, strict=True) if s[0] == "queued"]
        if queued:
            try:  # claims it unless another worker was quicker; its outcome is on its row
                run_job(ctx.runtime, _reporting_to(ctx, done, len(ids)), "map.drive", queued[0], ctx.enqueue)
            except Exception:  # re-queued for a retry (or failed after its last attempt): seen above
                log.warning("drive subtask %s hit an unexpected error", queued[0], exc_info=True)
        else:
            time.sleep(POLL_S)


def _reporting_to(parent: JobContext, done: int, n: int) -> TaskFn:
    """:func:`map_drive` run by the build itself, its progress also shown as the build's.

    A cancel of the build stops the subtask at once (it was asked to stop too); a build taken from this
    worker lets the subtask finish, since the build's next run can use it.
    """

    def task(ctx: JobContext) -> None:
        own = ctx.report

        def report(stage: str, fraction: float) -> None:
            own(stage, fraction)
            with contextlib.suppress(job_service.JobLost):
                parent.report("odometry", (done + fraction) / n)

        ctx.report = report
        map_drive(ctx)

    return task


def _stop_subtasks(ctx: JobContext) -> None:
    with ctx.runtime.storage.db.session() as session:
        job_service.cancel_children(session, ctx.job.id)


def map_build(ctx: JobContext) -> None:
    """Build the next map version of the job's site from ``map.drive`` subtasks. Args: ``preset``."""
    preset, params = _preset(ctx.args)
    label = f"{ctx.job.created_by or 'api'} via job {ctx.job.id}"
    storage = ctx.runtime.storage
    ctx.report("loading drives", 0.0)
    with storage.db.session() as session:
        site = _site(ctx, session)
        version = session.scalar(
            select(MapVersion).where(MapVersion.site_id == site.id, MapVersion.created_by == label)
        )
        if version is None:  # the normal case; a version of this job exists only if it already succeeded
            map_service.ensure_buildable(session, site)
            drives = [(d.id, d.frame_count) for d in map_drives.mapping_drives(session, site)]
    if version is not None:
        with storage.db.session() as session:
            ctx.succeed(session, _result(version))
        return
    try:
        ids = _subtasks(ctx, drives, preset)
        start = time.monotonic()
        results = _await_subtasks(ctx, ids)
        odometry_s = time.monotonic() - start
    except (DriftmapError, job_service.JobCancelled):
        _stop_subtasks(ctx)
        raise
    with storage.blobs.batch() as batch, storage.db.session() as session:
        site = _site(ctx, session)
        loaded = map_service.load_site_drives(session, storage.blobs, site)
        if [d.id for d in loaded.drives] != [d for d, _n in drives]:
            raise ConflictError("the site's mapping drives changed while its map was being built")
        pieces = _pieces(ctx, results, params, drives)
        prepared = join_drives(pieces, loaded.inputs, params, ctx.report, odometry_s)
        build = solve_map(prepared, loaded.inputs, params, ctx.report)
        version = map_service.store_map_version(session, batch, site, loaded, build, params, label)
        ctx.succeed(session, _result(version))  # no progress report from here: this transaction writes
    _drop_pieces(ctx, [str(r["piece_sha256"]) for r in results])


def _result(version: MapVersion) -> dict[str, Any]:
    return {
        "map_version_id": version.id,
        "version": version.version,
        "stats": map_service.json_safe(version.stats),
    }


def _pieces(
    ctx: JobContext, results: list[dict[str, Any]], params: MappingParams, drives: list[tuple[int, int]]
) -> list[PreparedDrive]:
    total, offset, out = sum(n for _d, n in drives), 0, []
    for result, (_drive_id, n) in zip(results, drives, strict=True):
        sha = str(result["piece_sha256"])
        if not ctx.runtime.storage.blobs.exists(sha):
            raise NotFoundError(
                f"job {ctx.job.id}: the odometry of drive {result['drive_id']} (blob {sha}) is gone"
            )
        data = ctx.runtime.storage.blobs.get(sha)
        out.append(map_drives.piece_from_bytes(data, params, (offset, total)))
        offset += n
    return out


def _drop_pieces(ctx: JobContext, shas: list[str]) -> None:
    """Delete the pieces' blobs unless a subtask of another unfinished build stored the same one."""
    storage = ctx.runtime.storage
    with storage.db.session() as session:
        open_builds = select(Job.id).where(Job.kind == "map.build", Job.status.in_(("queued", "running")))
        others = session.scalars(
            select(Job.result).where(
                Job.kind == "map.drive",
                Job.parent_id != ctx.job.id,
                Job.parent_id.in_(open_builds),
                Job.status == "succeeded",
            )
        )
        keep = {r.get("piece_sha256") for r in others if r}
    for sha in shas:
        if sha not in keep:
            storage.blobs.delete(sha)
