"""A stored drive's frames: list them (parallel arrays), append one to a drive built frame by frame, serve a
frame's image or a thumbnail of it, and localise every frame against a map version (a ``drive.localise``
job). The drive itself (upload, detail, rename, delete) is in :mod:`driftmap.api.drives`."""

from __future__ import annotations

from typing import Annotated

import cv2
import numpy as np
from fastapi import APIRouter, Depends, Query, Request, status
from fastapi.responses import Response
from sqlalchemy import select

from driftmap.api.deps import SURVEYOR, VIEWER, SessionDep, StorageDep, SurveyorDep
from driftmap.api.drives import drive_by_id
from driftmap.api.input_types import Count, Id, Seconds
from driftmap.api.jobs import ACCEPTED, QueueDep, accepted
from driftmap.api.schemas_data import FrameArrays, FrameRead, JobRead, LocaliseCreate
from driftmap.errors import BadInputError, BadRequestError, NotFoundError, PayloadTooLargeError
from driftmap.formats.frame_images import encode_png
from driftmap.services import jobs as job_service
from driftmap.services import uploads
from driftmap.store.models import Frame

router = APIRouter(tags=["drives"])
IMAGE_TYPES = {"image/png": ".png", "image/jpeg": ".jpg"}
THUMBNAIL_WIDTH_PX = 160


@router.get("/drives/{drive_id}/frames", dependencies=[Depends(VIEWER)])
def list_frames(
    drive_id: Id,
    session: SessionDep,
    offset: Annotated[Count, Query()] = 0,
    limit: Annotated[int, Query(ge=1, le=100_000)] = 10_000,
) -> FrameArrays:
    """A page of the drive's frames as parallel arrays (frame number, time, ground truth when known)."""
    drive = drive_by_id(session, drive_id)
    rows = session.execute(
        select(Frame.index, Frame.t_s, Frame.true_x_m, Frame.true_y_m)
        .where(Frame.drive_id == drive.id)
        .order_by(Frame.index)
        .offset(offset)
        .limit(limit)
    ).all()
    return FrameArrays(
        drive_id=drive.id,
        total=drive.frame_count,
        offset=offset,
        limit=limit,
        index=[r[0] for r in rows],
        t_s=[r[1] for r in rows],
        true_x_m=[r[2] for r in rows],
        true_y_m=[r[3] for r in rows],
    )


async def _image_body(request: Request) -> bytes:
    """The request body of a posted frame: PNG or JPEG bytes, within the frame size limit."""
    content_type = request.headers.get("content-type", "").split(";")[0].strip().lower()
    if content_type not in IMAGE_TYPES:
        raise BadRequestError(
            f"send the frame as the body with Content-Type image/png or image/jpeg, not {content_type or 'none'!r}",
            field="content-type",
        )
    limit: int = request.app.state.settings.max_frame_bytes
    chunks, total = [], 0
    async for chunk in request.stream():
        total += len(chunk)
        if total > limit:
            raise PayloadTooLargeError(f"frame is over the {limit} byte limit", field="body")
        chunks.append(chunk)
    if not total:
        raise BadRequestError("the request has no body: send the PNG or JPEG bytes", field="body")
    return b"".join(chunks)


@router.post(
    "/drives/{drive_id}/frames",
    status_code=status.HTTP_201_CREATED,
    dependencies=[Depends(SURVEYOR)],
    openapi_extra={
        "requestBody": {
            "required": True,
            "content": {key: {"schema": {"type": "string", "format": "binary"}} for key in IMAGE_TYPES},
        }
    },
)
def add_frame(
    drive_id: Id,
    data: Annotated[bytes, Depends(_image_body)],
    session: SessionDep,
    storage: StorageDep,
    t: Annotated[Seconds, Query(description="Seconds since the drive's start; must increase.")],
    index: Annotated[Count | None, Query(description="Frame number (default: one past the last).")] = None,
) -> FrameRead:
    """Append one frame (PNG or JPEG body of the camera's size) to a drive built frame by frame."""
    drive = drive_by_id(session, drive_id)
    with storage.blobs.batch() as batch:
        frame = uploads.append_frame(session, batch, drive, data, t_s=t, index=index)
        session.commit()
    return FrameRead.model_validate(frame)


def _frame(session: SessionDep, drive_id: Id, index: int) -> Frame:
    frame = session.scalar(select(Frame).where(Frame.drive_id == drive_id, Frame.index == index))
    if frame is None:
        drive_by_id(session, drive_id)
        raise NotFoundError(f"drive {drive_id} has no frame {index}")
    return frame


def _image_response(data: bytes, media_type: str, etag: str) -> Response:
    headers = {"ETag": f'"{etag}"', "Cache-Control": "private, max-age=86400, immutable"}
    return Response(data, media_type=media_type, headers=headers)


_IMAGE_RESPONSES: dict[int | str, dict[str, object]] = {200: {"content": {"image/png": {}, "image/jpeg": {}}}}


@router.get(
    "/drives/{drive_id}/frames/{index}",
    dependencies=[Depends(VIEWER)],
    response_class=Response,
    responses=_IMAGE_RESPONSES,
)
def frame_image(drive_id: Id, index: Count, session: SessionDep, storage: StorageDep) -> Response:
    """The frame's original image file (PNG or JPEG, as recorded)."""
    frame = _frame(session, drive_id, index)
    media = "image/png" if frame.image_ext == ".png" else "image/jpeg"
    return _image_response(storage.blobs.get(frame.blob_sha256), media, frame.blob_sha256)


@router.get(
    "/drives/{drive_id}/frames/{index}/thumbnail",
    dependencies=[Depends(VIEWER)],
    response_class=Response,
    responses={200: {"content": {"image/png": {}}}},
)
def frame_thumbnail(
    drive_id: Id,
    index: Count,
    session: SessionDep,
    storage: StorageDep,
    width: Annotated[int, Query(ge=16, le=1024, description="Thumbnail width, pixels.")] = THUMBNAIL_WIDTH_PX,
) -> Response:
    """A small PNG of the frame, ``width`` pixels wide (never wider than the frame)."""
    frame = _frame(session, drive_id, index)
    image = cv2.imdecode(
        np.frombuffer(storage.blobs.get(frame.blob_sha256), dtype=np.uint8),
        cv2.IMREAD_UNCHANGED,
    )
    if image is None:
        raise BadInputError(f"frame {index} of drive {drive_id} cannot be decoded", field="index")
    height_px, width_px = image.shape[:2]
    if width < width_px:
        size = (width, max(1, round(height_px * width / width_px)))
        image = cv2.resize(image, size, interpolation=cv2.INTER_AREA)
    return _image_response(
        encode_png(np.asarray(image, dtype=np.uint8)), "image/png", f"{frame.blob_sha256}-{width}"
    )


@router.post("/drives/{drive_id}/localise", status_code=status.HTTP_202_ACCEPTED, responses=ACCEPTED)
def localise_drive(
    request: Request,
    response: Response,
    drive_id: Id,
    body: LocaliseCreate,
    session: SessionDep,
    queue: QueueDep,
    user: SurveyorDep,
) -> JobRead:
    """Localise every frame of a stored drive against a map version (a ``drive.localise`` job)."""
    drive = drive_by_id(session, drive_id)
    args = {"drive_id": drive.id, **body.model_dump()}
    job = job_service.submit(
        session, queue.enqueue, "drive.localise", args, site_id=drive.site_id, created_by=user.name
    )
    return accepted(request, response, job)
