"""Drives: create an empty one (to be filled frame by frame), upload one (zip of a drive folder, or video +
calibration), list, detail, rename and delete; and :func:`drive_by_id`, the path's drive for every drive
route. A drive's frames and its localisation are in :mod:`driftmap.api.drive_frames`."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Annotated

from fastapi import APIRouter, Depends, Form, Query, Request, UploadFile, status
from fastapi.responses import Response
from sqlalchemy import select

from driftmap.api.deps import ADMIN, SURVEYOR, VIEWER, SessionDep, SettingsDep, StorageDep, SurveyorDep
from driftmap.api.input_types import Count, Id, Name
from driftmap.api.jobs import ACCEPTED, QueueDep, accepted
from driftmap.api.schemas_data import DriveCreate, DriveKind, DriveRead, DriveUpdate, JobRead, Page, paged
from driftmap.api.sites import site_by_id
from driftmap.api.upload_limits import check_content_length, read_limited
from driftmap.errors import BadInputError, BadRequestError, ConflictError, NotFoundError
from driftmap.services import deletion, uploads
from driftmap.services import drives as drive_service
from driftmap.services import jobs as job_service
from driftmap.services.cameras import profiles as profile_service
from driftmap.store.models import Drive

router = APIRouter(tags=["drives"])
CALIBRATION_MAX_BYTES = 1024 * 1024


def drive_by_id(session: SessionDep, drive_id: Id) -> Drive:
    """The drive of the path's ``drive_id`` (404 when missing)."""
    drive = session.get(Drive, drive_id)
    if drive is None:
        raise NotFoundError(f"no drive with id {drive_id}")
    return drive


def _read(session: SessionDep, drive: Drive) -> DriveRead:
    site = site_by_id(session, drive.site_id)
    summary = next(s for s in drive_service.list_drives(session, site) if s.id == drive.id)
    return DriveRead(
        **vars(summary),
        site_id=drive.site_id,
        source=drive.source,
        camera=drive.camera,
        created_at=drive.created_at,
    )


@router.get("/sites/{site_id}/drives", dependencies=[Depends(VIEWER)])
def list_drives(
    site_id: Id,
    session: SessionDep,
    offset: Annotated[Count, Query()] = 0,
    limit: Annotated[int, Query(ge=1, le=500)] = 100,
) -> Page[DriveRead]:
    """The site's drives, oldest first, with duration, grounding count and whether they have ground truth."""
    site = site_by_id(session, site_id)
    summaries = drive_service.list_drives(session, site)
    drives = {d.id: d for d in session.scalars(select(Drive).where(Drive.site_id == site.id))}
    return paged(
        summaries,
        offset,
        limit,
        lambda s: DriveRead(
            **vars(s),
            site_id=site.id,
            source=drives[s.id].source,
            camera=drives[s.id].camera,
            created_at=drives[s.id].created_at,
        ),
    )


@router.post("/sites/{site_id}/drives", status_code=status.HTTP_201_CREATED)
def create_drive(site_id: Id, body: DriveCreate, session: SessionDep, _user: SurveyorDep) -> DriveRead:
    """An empty drive; post its frames one by one to ``/api/drives/{id}/frames``."""
    drive = uploads.create_empty_drive(
        session,
        site_by_id(session, site_id),
        name=body.name,
        kind=body.kind,
        fps=body.fps,
        camera=body.camera.model_dump(),
    )
    return _read(session, drive)


def _ensure_new_name(session: SessionDep, site_id: Id, name: str) -> None:
    if session.scalar(select(Drive.id).where(Drive.site_id == site_id, Drive.name == name)) is not None:
        raise ConflictError(f"the site already has a drive named {name!r}")


@router.post(
    "/sites/{site_id}/drives/zip",
    status_code=status.HTTP_202_ACCEPTED,
    responses=ACCEPTED,
    dependencies=[Depends(SURVEYOR), Depends(check_content_length)],
)
def upload_drive_zip(
    request: Request,
    response: Response,
    site_id: Id,
    file: UploadFile,
    session: SessionDep,
    storage: StorageDep,
    settings: SettingsDep,
    queue: QueueDep,
    user: SurveyorDep,
    profile: Annotated[
        Id | None,
        Form(
            description="A camera profile's id: the drive was recorded with it (replaces drive.json's camera)."
        ),
    ] = None,
) -> JobRead:
    """Upload a zipped drive folder (multipart field ``file``); it is checked now and imported by a job. With
    ``profile``, the drive is imported with that stored camera instead of its ``drive.json`` block."""
    site = site_by_id(session, site_id)
    filename = Path(file.filename or "drive.zip").name
    scratch = uploads.scratch_dir(settings.data_dir, "upload-")
    camera_data = None
    try:
        zip_path = scratch / "upload.zip"
        uploads.save_upload(file.file, zip_path, max_bytes=settings.max_upload_bytes, filename=filename)
        folder = uploads.unpack_drive_zip(
            zip_path, scratch / "unpacked", label=filename, max_bytes=settings.max_upload_bytes
        )
        if profile is not None:
            record = profile_service.get_profile(session, profile)
            drive_service.with_camera(folder, profile_service.profile_camera(record))
            camera_data = json.dumps({"camera": record.camera}).encode()
        _ensure_new_name(session, site.id, folder.meta.name)
        sha = uploads.store_file_as_blob(storage.blobs, zip_path)
    finally:
        uploads.remove_tree(scratch)
    args = {"format": "zip", "upload_sha256": sha, "filename": filename, "name": folder.meta.name}
    if camera_data is not None:
        args["calibration_sha256"], _created = storage.blobs.put(camera_data)
    job = job_service.submit(
        session, queue.enqueue, "drive.import", args, site_id=site.id, created_by=user.name
    )
    return accepted(request, response, job)


@router.post(
    "/sites/{site_id}/drives/video",
    status_code=status.HTTP_202_ACCEPTED,
    responses=ACCEPTED,
    dependencies=[Depends(SURVEYOR), Depends(check_content_length)],
)
def upload_drive_video(
    request: Request,
    response: Response,
    site_id: Id,
    video: UploadFile,
    session: SessionDep,
    storage: StorageDep,
    settings: SettingsDep,
    queue: QueueDep,
    user: SurveyorDep,
    calibration: UploadFile | None = None,
    profile: Annotated[
        Id | None, Form(description="A camera profile's id, instead of a calibration file.")
    ] = None,
    name: Annotated[Name | None, Form(description="Drive name (default: the video's file stem).")] = None,
    kind: Annotated[DriveKind, Form()] = "mapping",
) -> JobRead:
    """Upload a video (mp4/avi/mov/mkv) with its calibration JSON (the ``camera`` block, optional ``fps``) or
    the id of a stored camera profile (``profile``) whose block it was recorded with: one of the two."""
    site = site_by_id(session, site_id)
    filename = Path(video.filename or "drive.mp4").name
    if Path(filename).suffix.lower() not in drive_service.VIDEO_SUFFIXES:
        raise BadRequestError(f"not a video file ({', '.join(drive_service.VIDEO_SUFFIXES)})", file=filename)
    if (calibration is None) == (profile is None):
        raise BadInputError("send either a calibration file or a camera profile's id", field="calibration")
    if calibration is not None:
        calibration_name = Path(calibration.filename or "calibration.json").name
        calibration_data = read_limited(calibration, CALIBRATION_MAX_BYTES, calibration_name)
    elif profile is not None:
        record = profile_service.get_profile(session, profile)
        calibration_name = f"camera profile {record.name!r}"
        calibration_data = json.dumps({"camera": record.camera}).encode()
    uploads.check_calibration(calibration_data, calibration_name)
    drive_name = (name or Path(filename).stem).strip()
    _ensure_new_name(session, site.id, drive_name)
    scratch = uploads.scratch_dir(settings.data_dir, "upload-")
    try:
        video_path = scratch / filename
        uploads.save_upload(video.file, video_path, max_bytes=settings.max_upload_bytes, filename=filename)
        sha = uploads.store_file_as_blob(storage.blobs, video_path)
    finally:
        uploads.remove_tree(scratch)
    calibration_sha, _created = storage.blobs.put(calibration_data)
    args = {
        "format": "video",
        "upload_sha256": sha,
        "calibration_sha256": calibration_sha,
        "filename": filename,
        "name": drive_name,
        "kind": kind,
    }
    job = job_service.submit(
        session, queue.enqueue, "drive.import", args, site_id=site.id, created_by=user.name
    )
    return accepted(request, response, job)


@router.get("/drives/{drive_id}", dependencies=[Depends(VIEWER)])
def get_drive(drive_id: Id, session: SessionDep) -> DriveRead:
    """One drive with its camera block."""
    return _read(session, drive_by_id(session, drive_id))


@router.patch("/drives/{drive_id}")
def update_drive(drive_id: Id, body: DriveUpdate, session: SessionDep, _user: SurveyorDep) -> DriveRead:
    """Rename a drive."""
    drive = drive_by_id(session, drive_id)
    if body.name is not None and body.name.strip() != drive.name:
        _ensure_new_name(session, drive.site_id, body.name.strip())
        drive.name = body.name.strip()
        session.flush()
    return _read(session, drive)


@router.delete("/drives/{drive_id}", status_code=status.HTTP_204_NO_CONTENT, dependencies=[Depends(ADMIN)])
def delete_drive(drive_id: Id, session: SessionDep, storage: StorageDep) -> None:
    """Delete a drive with its frames, groundings and the frame images no other drive uses."""
    candidates = deletion.delete_drive(session, drive_by_id(session, drive_id))
    session.commit()
    deletion.delete_unreferenced_blobs(storage, candidates)
