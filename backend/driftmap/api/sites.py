"""Sites and their survey plans: CRUD, DXF upload, plan layers as simplified GeoJSON, simulated sites."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Query, Request, Response, UploadFile, status
from sqlalchemy import select

from driftmap.api.deps import ADMIN, SURVEYOR, VIEWER, AdminDep, SessionDep, SettingsDep, StorageDep
from driftmap.api.input_types import Count, Id
from driftmap.api.jobs import ACCEPTED, QueueDep, accepted
from driftmap.api.schemas_data import (
    JobRead,
    Page,
    SiteCreate,
    SiteCrsBody,
    SiteRead,
    SiteSimulate,
    SiteUpdate,
    SurveyLayersRead,
    SurveyMapRead,
    paged,
)
from driftmap.api.upload_limits import check_content_length, read_limited
from driftmap.errors import BadInputError, ConflictError
from driftmap.formats.site_crs import SiteCrs
from driftmap.services import deletion, survey_layers
from driftmap.services import jobs as job_service
from driftmap.services import sites as site_service
from driftmap.store.models import Site, SurveyMap

router = APIRouter(tags=["sites"])


def site_by_id(session: SessionDep, site_id: Id) -> Site:
    """The site of the path's ``site_id`` (404 when missing)."""
    return site_service.get_site(session, site_id)


@router.get("/sites", dependencies=[Depends(VIEWER)])
def list_sites(
    session: SessionDep,
    offset: Annotated[Count, Query()] = 0,
    limit: Annotated[int, Query(ge=1, le=500)] = 100,
) -> Page[SiteRead]:
    """Every site, oldest first."""
    return paged(site_service.list_sites(session), offset, limit, SiteRead.model_validate)


@router.post("/sites", status_code=status.HTTP_201_CREATED, dependencies=[Depends(ADMIN)])
def create_site(body: SiteCreate, session: SessionDep) -> SiteRead:
    """A new, empty site (then upload its survey plan and drives)."""
    return SiteRead.model_validate(site_service.create_site(session, body.name, body.description))


@router.post("/sites/simulate", status_code=status.HTTP_202_ACCEPTED, responses=ACCEPTED)
def simulate_site(
    request: Request,
    response: Response,
    body: SiteSimulate,
    session: SessionDep,
    queue: QueueDep,
    user: AdminDep,
) -> JobRead:
    """Render a synthetic mine and import it as a new site (a ``site.simulate`` job)."""
    if session.scalar(select(Site.id).where(Site.name == body.name.strip())) is not None:
        raise ConflictError(f"a site named {body.name.strip()!r} already exists")
    job = job_service.submit(session, queue.enqueue, "site.simulate", body.model_dump(), created_by=user.name)
    return accepted(request, response, job)


@router.get("/sites/{site_id}", dependencies=[Depends(VIEWER)])
def get_site(site_id: Id, session: SessionDep) -> SiteRead:
    """One site."""
    return SiteRead.model_validate(site_by_id(session, site_id))


@router.patch("/sites/{site_id}", dependencies=[Depends(ADMIN)])
def update_site(site_id: Id, body: SiteUpdate, session: SessionDep) -> SiteRead:
    """Rename a site or change its description."""
    site = site_by_id(session, site_id)
    if body.name is not None and body.name.strip() != site.name:
        name = body.name.strip()
        if session.scalar(select(Site.id).where(Site.name == name)) is not None:
            raise ConflictError(f"a site named {name!r} already exists")
        site.name = name
    if body.description is not None:
        site.description = body.description
    session.flush()
    return SiteRead.model_validate(site)


@router.put("/sites/{site_id}/crs", dependencies=[Depends(SURVEYOR)])
def set_site_crs(site_id: Id, body: SiteCrsBody, session: SessionDep) -> SiteRead:
    """Place the site plane on the mine grid and, with an EPSG code, on the Earth (GeoJSON and KML exports are
    then WGS84); a body of defaults clears it. An unknown or unprojected EPSG code is 422 naming crs.epsg."""
    site = site_by_id(session, site_id)
    site_service.set_site_crs(session, site, SiteCrs(**body.model_dump()))
    return SiteRead.model_validate(site)


@router.delete("/sites/{site_id}", status_code=status.HTTP_204_NO_CONTENT, dependencies=[Depends(ADMIN)])
def delete_site(site_id: Id, session: SessionDep, storage: StorageDep) -> None:
    """Delete a site with its plans, drives, frames, groundings, map versions and jobs."""
    candidates = deletion.delete_site(session, site_by_id(session, site_id))
    session.commit()
    deletion.delete_unreferenced_blobs(storage, candidates)


@router.post(
    "/sites/{site_id}/survey",
    status_code=status.HTTP_201_CREATED,
    dependencies=[Depends(ADMIN), Depends(check_content_length)],
)
def upload_survey(
    site_id: Id, file: UploadFile, session: SessionDep, storage: StorageDep, settings: SettingsDep
) -> SurveyMapRead:
    """Upload the site's surveyed DXF plan (multipart field ``file``); the newest plan is the one in use."""
    site = site_by_id(session, site_id)
    filename = file.filename or "survey.dxf"
    limits = site_service.survey_limits(settings)
    data = read_limited(file, min(settings.max_upload_bytes, limits.max_file_bytes), filename)
    with storage.blobs.batch() as batch:
        record = site_service.add_survey_map(session, batch, site, data, filename, limits)
        session.commit()
    return SurveyMapRead.model_validate(record)


@router.get("/sites/{site_id}/survey", dependencies=[Depends(VIEWER)])
def list_survey_maps(site_id: Id, session: SessionDep) -> list[SurveyMapRead]:
    """The site's uploaded plans, newest first."""
    site = site_by_id(session, site_id)
    rows = session.scalars(
        select(SurveyMap).where(SurveyMap.site_id == site.id).order_by(SurveyMap.id.desc())
    )
    return [SurveyMapRead.model_validate(r) for r in rows]


@router.get("/sites/{site_id}/survey/layers", dependencies=[Depends(VIEWER)])
def survey_layers_of(
    site_id: Id,
    session: SessionDep,
    zoom: Annotated[float | None, Query(description="Map zoom (0: the plan spans 256 px).")] = None,
    tolerance_m: Annotated[float | None, Query(description="Simplification tolerance, metres.")] = None,
    layers: Annotated[str | None, Query(description="Comma-separated layer names (default all).")] = None,
) -> SurveyLayersRead:
    """The newest plan's layers as GeoJSON in plane metres, simplified for ``zoom`` or to ``tolerance_m``."""
    if zoom is not None and tolerance_m is not None:
        raise BadInputError("give zoom or tolerance_m, not both", field="zoom")
    survey = site_service.latest_survey_map(session, site_by_id(session, site_id))
    tolerance = tolerance_m if tolerance_m is not None else 0.0
    if zoom is not None:
        tolerance = survey_layers.tolerance_for_zoom(survey, zoom)
    names = [n for n in layers.split(",") if n] if layers else None
    return SurveyLayersRead(
        **survey_layers.survey_layers(survey, tolerance_m=tolerance, layers=names, session=session)
    )
