"""Groundings: create from a drive's frame and a surveyed point, move, enable or disable, name the station,
delete, list with the residuals of the latest map, and import/export a drive's ``groundings.csv`` or a
site's control file."""

from __future__ import annotations

from typing import Annotated
from urllib.parse import quote

from fastapi import APIRouter, Depends, Query, UploadFile, status
from fastapi.responses import Response

from driftmap.api.deps import VIEWER, SessionDep, SurveyorDep
from driftmap.api.drives import drive_by_id
from driftmap.api.input_types import Count, Id
from driftmap.api.schemas_data import (
    GroundingCreate,
    GroundingImportRead,
    GroundingRead,
    GroundingUpdate,
    Page,
    SiteGroundingImportRead,
)
from driftmap.api.sites import site_by_id
from driftmap.api.upload_limits import read_limited
from driftmap.services import groundings as grounding_service

router = APIRouter(tags=["groundings"])
CSV_MAX_BYTES = 16 * 1024 * 1024


def attachment(filename: str) -> str:
    """A ``Content-Disposition`` header value for downloading ``filename`` (RFC 6266).

    ``filename*`` carries the name as percent-encoded UTF-8 (RFC 5987); the plain ``filename`` is an ASCII
    fallback for old clients, with control characters, quotes, backslashes and non-ASCII letters as ``_``.
    """
    ascii_name = "".join(c if " " <= c <= "~" and c not in '"\\' else "_" for c in filename)
    utf8 = quote(filename.encode("utf-8", "backslashreplace"), safe="")
    return f"attachment; filename=\"{ascii_name}\"; filename*=UTF-8''{utf8}"


def _view(session: SessionDep, site_id: Id, grounding_id: Id) -> GroundingRead:
    views, _total = grounding_service.list_groundings(session, site_id, limit=1_000_000)
    return GroundingRead.model_validate(next(v for v in views if v.id == grounding_id))


@router.get("/sites/{site_id}/groundings", dependencies=[Depends(VIEWER)])
def list_groundings(
    site_id: Id,
    session: SessionDep,
    drive_id: Id | None = None,
    offset: Annotated[Count, Query()] = 0,
    limit: Annotated[int, Query(ge=1, le=10_000)] = 1000,
) -> Page[GroundingRead]:
    """The site's groundings (or one drive's), with each one's residual in the latest map version."""
    site = site_by_id(session, site_id)
    views, total = grounding_service.list_groundings(session, site.id, drive_id, offset, limit)
    return Page[GroundingRead](
        items=[GroundingRead.model_validate(v) for v in views], total=total, offset=offset, limit=limit
    )


@router.post("/drives/{drive_id}/groundings", status_code=status.HTTP_201_CREATED)
def create_grounding(
    drive_id: Id, body: GroundingCreate, session: SessionDep, user: SurveyorDep
) -> GroundingRead:
    """Ground a frame of a mapping drive at a surveyed point (x east, y north, metres)."""
    drive = drive_by_id(session, drive_id)
    grounding = grounding_service.create_grounding(
        session, drive, body.frame, body.x, body.y, user.name, station=body.station, enabled=body.enabled
    )
    return _view(session, drive.site_id, grounding.id)


@router.patch("/groundings/{grounding_id}")
def update_grounding(
    grounding_id: Id, body: GroundingUpdate, session: SessionDep, _user: SurveyorDep
) -> GroundingRead:
    """Move a grounding's surveyed point, enable or disable it for map builds, or set its survey station."""
    grounding = grounding_service.get_grounding(session, grounding_id)
    station = (body.station or "") if "station" in body.model_fields_set else None
    grounding_service.update_grounding(
        session, grounding, x_m=body.x, y_m=body.y, enabled=body.enabled, station=station
    )
    return _view(session, drive_by_id(session, grounding.drive_id).site_id, grounding.id)


@router.delete("/groundings/{grounding_id}", status_code=status.HTTP_204_NO_CONTENT)
def delete_grounding(grounding_id: Id, session: SessionDep, _user: SurveyorDep) -> None:
    """Remove a grounding."""
    grounding_service.delete_grounding(session, grounding_service.get_grounding(session, grounding_id))


@router.get(
    "/drives/{drive_id}/groundings.csv",
    dependencies=[Depends(VIEWER)],
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}},
)
def export_groundings(drive_id: Id, session: SessionDep) -> Response:
    """The drive's groundings as ``groundings.csv`` (``frame,x,y``)."""
    drive = drive_by_id(session, drive_id)
    return Response(
        grounding_service.export_csv(session, drive),
        media_type="text/csv",
        headers={"Content-Disposition": attachment(f"{drive.name}-groundings.csv")},
    )


@router.put("/drives/{drive_id}/groundings.csv")
def import_groundings(
    drive_id: Id, file: UploadFile, session: SessionDep, user: SurveyorDep
) -> GroundingImportRead:
    """Replace the drive's groundings with a ``groundings.csv`` (multipart ``file``); errors name the line."""
    drive = drive_by_id(session, drive_id)
    filename = file.filename or "groundings.csv"
    data = read_limited(file, CSV_MAX_BYTES, filename)
    count = grounding_service.import_csv(session, drive, data, filename, user.name)
    return GroundingImportRead(drive_id=drive.id, imported=count)


@router.get(
    "/sites/{site_id}/groundings.csv",
    dependencies=[Depends(VIEWER)],
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}},
)
def export_site_groundings(site_id: Id, session: SessionDep) -> Response:
    """The site's survey control file: every grounding as ``drive,frame,station,x,y,enabled``."""
    site = site_by_id(session, site_id)
    return Response(
        grounding_service.export_site_csv(session, site.id),
        media_type="text/csv",
        headers={"Content-Disposition": attachment(f"{site.name}-groundings.csv")},
    )


@router.put("/sites/{site_id}/groundings.csv")
def import_site_groundings(
    site_id: Id, file: UploadFile, session: SessionDep, user: SurveyorDep
) -> SiteGroundingImportRead:
    """Replace all the site's groundings with a control file (multipart ``file``); errors name line and field."""
    site = site_by_id(session, site_id)
    filename = file.filename or "groundings.csv"
    data = read_limited(file, CSV_MAX_BYTES, filename)
    count = grounding_service.import_site_csv(session, site.id, data, filename, user.name)
    return SiteGroundingImportRead(site_id=site.id, imported=count)
