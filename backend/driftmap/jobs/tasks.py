"""The job kinds: ``map.build`` (with its ``map.drive`` subtasks, :mod:`driftmap.jobs.map_tasks`),
``drive.import``, ``drive.localise``, ``site.simulate``.

Each task reads its arguments from the job row, does its work through the services, and writes all of its
output together with ``succeeded`` in ONE transaction at the end (:meth:`JobContext.succeed`), with new blobs
tracked by a :class:`~driftmap.store.blobs.BlobBatch`. A worker killed half-way therefore leaves no rows and
no new blobs behind, and running a job twice cannot store its output twice: the second run finds the job no
longer queued, or loses the final conditional update and rolls back.
"""

from __future__ import annotations

import logging
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.errors import ConflictError, DriftmapError, NotFoundError
from driftmap.formats.csv_exports import localisation_text
from driftmap.formats.frame_images import decode_gray
from driftmap.jobs.loop_tasks import map_loops
from driftmap.jobs.map_tasks import map_build, map_drive
from driftmap.jobs.runtime import JobContext
from driftmap.services import drives as drive_service
from driftmap.services import localisation as loc_service
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.services import uploads
from driftmap.services.jobs import JobCancelled
from driftmap.services.uploads import relabelled
from driftmap.sim import simulate_site
from driftmap.store.job_models import Job
from driftmap.store.models import Drive, Site

log = logging.getLogger(__name__)


def _site(ctx: JobContext, session: Session) -> Site:
    site = session.get(Site, ctx.job.site_id) if ctx.job.site_id is not None else None
    if site is None:
        raise NotFoundError(f"job {ctx.job.id}: site {ctx.job.site_id} does not exist (any more)")
    return site


def _scratch(ctx: JobContext) -> tempfile.TemporaryDirectory[str]:
    root = ctx.runtime.settings.data_dir / "tmp"
    root.mkdir(parents=True, exist_ok=True)
    return tempfile.TemporaryDirectory(prefix=f"job-{ctx.job.id}-", dir=root)


def _copy_blob(ctx: JobContext, sha: str, dest: Path) -> None:
    source = ctx.runtime.storage.blobs.path_of(sha)
    if not source.is_file():
        raise NotFoundError(f"job {ctx.job.id}: the uploaded file (blob {sha}) is gone; upload it again")
    shutil.copyfile(source, dest)


def _other_jobs_use(ctx: JobContext, session: Session, sha: str) -> bool:
    args = session.scalars(
        select(Job.args).where(
            Job.kind == "drive.import", Job.id != ctx.job.id, Job.status.in_(("queued", "running"))
        )
    )
    return any(sha in (a.get("upload_sha256"), a.get("calibration_sha256")) for a in args)


def drive_import(ctx: JobContext) -> None:
    """Import an uploaded drive into the job's site.

    Args (job row): ``upload_sha256`` (blob of the zip or video), ``filename``, ``format`` (``zip`` or
    ``video``); for a video ``calibration_sha256``, ``name`` and ``kind``; for a zip an optional
    ``calibration_sha256`` (a camera profile's block replacing the folder's).
    """
    try:
        _import_upload(ctx)
    except (DriftmapError, JobCancelled):  # final outcomes: the upload will not be needed again
        drop_upload(ctx)
        raise
    drop_upload(ctx)


def _import_upload(ctx: JobContext) -> None:
    args = ctx.args
    storage = ctx.runtime.storage
    filename = Path(str(args.get("filename", "upload"))).name
    with _scratch(ctx) as scratch:
        work = Path(scratch)
        data_path = work / filename
        _copy_blob(ctx, str(args["upload_sha256"]), data_path)
        calibration: str | None = None
        if args.get("format") == "zip":
            folder = uploads.unpack_drive_zip(
                data_path, work / "unpacked", label=filename, max_bytes=ctx.runtime.settings.max_upload_bytes
            )
            source = folder.path
            if args.get("calibration_sha256"):  # a camera profile's block replacing drive.json's
                calibration_path = work / "calibration.json"
                _copy_blob(ctx, str(args["calibration_sha256"]), calibration_path)
                calibration = str(calibration_path)
        else:
            source = data_path
            calibration_path = work / "calibration.json"
            _copy_blob(ctx, str(args["calibration_sha256"]), calibration_path)
            calibration = str(calibration_path)
        ctx.report("import", 0.0)
        with (
            relabelled(work / "unpacked", filename),
            storage.blobs.batch() as batch,
            storage.db.session() as session,
        ):
            drive = drive_service.import_drive(
                session,
                batch,
                _site(ctx, session),
                source,
                progress=ctx.report,
                calibration=calibration,
                name=args.get("name"),
                kind=str(args.get("kind", "mapping")),
            )
            ctx.succeed(session, {"drive_id": drive.id, "name": drive.name, "frames": drive.frame_count})


def drop_upload(ctx: JobContext) -> None:
    """Delete the uploaded blobs of a finished drive.import job that no other waiting job uses."""
    storage = ctx.runtime.storage
    with storage.db.session() as session:
        for key in ("upload_sha256", "calibration_sha256"):
            sha = ctx.args.get(key)
            if isinstance(sha, str) and not _other_jobs_use(ctx, session, sha):
                storage.blobs.delete(sha)


def drive_localise(ctx: JobContext) -> None:
    """Localise a stored drive against a map version of its site; the CSV is kept as a blob.

    Args (job row): ``drive_id``; optional ``map_version`` (default latest), ``sesame`` and ``temporal``
    (default true). Result: counts, the map version, ``csv_sha256`` of the formats.md localisation CSV and,
    when the drive has ground truth, the median position error.
    """
    args = ctx.args
    storage = ctx.runtime.storage
    ctx.report("loading map", 0.0)
    with storage.db.session() as session:
        drive = session.get(Drive, int(args["drive_id"]))
        if drive is None:
            raise NotFoundError(f"job {ctx.job.id}: drive {args['drive_id']} does not exist (any more)")
        site = session.get(Site, drive.site_id)
        assert site is not None
        version = map_service.get_map_version(session, site, args.get("map_version"))
        lmap = loc_service.load_version_localiser_map(session, storage.blobs, version)
        sesame = loc_service.sesame_params_of(version) if args.get("sesame", True) else None
        frames = drive_service.frame_rows(session, drive)
        camera = drive_service.drive_meta(drive).camera
        number = version.version
    localiser = loc_service.make_localiser(
        lmap,
        sesame=sesame,
        temporal=bool(args.get("temporal", True)),
        camera=camera,
        odometry=bool(args.get("odometry", True)),
    )
    images = (decode_gray(storage.blobs.get(f.blob_sha256), f"frame {f.index}") for f in frames)
    estimates = loc_service.localise_frames(localiser, images, [f.t_s for f in frames], ctx.report)
    rows = loc_service.estimate_rows([f.index for f in frames], estimates)
    errors = [
        float(((r.x_m - f.true_x_m) ** 2 + (r.y_m - f.true_y_m) ** 2) ** 0.5)
        for r, f in zip(rows, frames, strict=True)
        if f.true_x_m is not None and f.true_y_m is not None
    ]
    result: dict[str, Any] = {
        "drive_id": drive.id,
        "map_version": number,
        "frames": len(rows),
        "matched": sum(int(r.matched) for r in rows),
        "median_error_m": sorted(errors)[len(errors) // 2] if errors else None,
    }
    with storage.blobs.batch() as batch, storage.db.session() as session:
        result["csv_sha256"] = batch.put(localisation_text(rows).encode())
        ctx.succeed(session, result)


def site_simulate(ctx: JobContext) -> None:
    """Simulate a site and import it (survey and every drive) as a new site, all in one transaction.

    Args (job row): ``name``, ``seed``, ``size`` (tiny|small|medium|large), ``obscurants`` (default false),
    optional ``max_frames_per_drive``. Result: ``site_id`` and the drive count.
    """
    args = ctx.args
    storage = ctx.runtime.storage
    name = str(args.get("name", "")).strip()
    with storage.db.session() as session:  # fail before minutes of rendering, not after
        if session.scalar(select(Site.id).where(Site.name == name)) is not None:
            raise ConflictError(f"a site named {name!r} already exists")
    with _scratch(ctx) as scratch:
        out = Path(scratch) / "site"
        simulate_site(
            out,
            seed=int(args.get("seed", 0)),
            size=str(args.get("size", "tiny")),
            obscurants=bool(args.get("obscurants", False)),
            progress=lambda stage, fraction: ctx.report(f"simulate: {stage}", fraction),
            workers=1,
            max_frames_per_drive=args.get("max_frames_per_drive"),
        )
        folders = drive_service.drive_folders_in(out / "drives")
        ctx.report("import", 0.0)  # the last report: the import below holds the write lock from its start
        with storage.blobs.batch() as batch, storage.db.session() as session:
            site = site_service.create_site(session, name)
            site_service.add_survey_map(session, batch, site, (out / "survey.dxf").read_bytes(), "survey.dxf")
            for folder in folders:
                drive_service.import_drive(session, batch, site, folder)
            job = session.get(Job, ctx.job.id)
            assert job is not None
            job.site_id = site.id
            ctx.succeed(session, {"site_id": site.id, "name": site.name, "drives": len(folders)})


__all__ = [
    "TASKS",
    "drive_import",
    "drive_localise",
    "map_build",
    "map_drive",
    "map_loops",
    "site_simulate",
]

TASKS: dict[str, Callable[[JobContext], None]] = {
    "map.build": map_build,
    "map.drive": map_drive,
    "map.loops": map_loops,
    "drive.import": drive_import,
    "drive.localise": drive_localise,
    "site.simulate": site_simulate,
}
"""Job kind -> task function; every kind of :data:`driftmap.services.jobs.QUEUE_KINDS`."""
