"""Map versions: start a build (a ``map.build`` job), list, detail, poses, loop closures, nodes, residuals,
compare two versions, delete."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Query, Request, Response, status

from driftmap.api.deps import ADMIN, VIEWER, SessionDep, StorageDep, SurveyorDep
from driftmap.api.groundings import attachment
from driftmap.api.input_types import Count, Id
from driftmap.api.jobs import ACCEPTED, QueueDep, accepted
from driftmap.api.schemas_data import JobRead, Page
from driftmap.api.schemas_maps import (
    ClosureRead,
    MapBuildCreate,
    MapCompareRead,
    MapVersionDetail,
    MapVersionRead,
    NodeArrays,
    PoseArrays,
    ResidualRead,
    ResidualSummaryRead,
)
from driftmap.api.sites import site_by_id
from driftmap.services import deletion, map_views, residuals
from driftmap.services import maps as map_service
from driftmap.store.models import MapVersion

router = APIRouter(tags=["maps"])


def _version(session: SessionDep, site_id: Id, version: Id) -> MapVersion:
    return map_service.get_map_version(session, site_by_id(session, site_id), version)


@router.post("/sites/{site_id}/maps", status_code=status.HTTP_202_ACCEPTED, responses=ACCEPTED)
def build_map(
    request: Request,
    response: Response,
    site_id: Id,
    body: MapBuildCreate,
    session: SessionDep,
    queue: QueueDep,
    user: SurveyorDep,
) -> JobRead:
    """Start building the next map version from the site's mapping drives and groundings (a job); 409 while
    another build of the site is queued or running."""
    site = site_by_id(session, site_id)
    job = map_service.submit_build(session, queue.enqueue, site, body.model_dump(), user.name)
    return accepted(request, response, job)


@router.get("/sites/{site_id}/maps", dependencies=[Depends(VIEWER)])
def list_versions(
    site_id: Id,
    session: SessionDep,
    offset: Annotated[Count, Query()] = 0,
    limit: Annotated[int, Query(ge=1, le=500)] = 50,
) -> Page[MapVersionRead]:
    """The site's map versions, newest first."""
    rows, total = map_views.list_versions(session, site_by_id(session, site_id).id, offset, limit)
    return Page[MapVersionRead](
        items=[MapVersionRead.model_validate(v) for v in rows], total=total, offset=offset, limit=limit
    )


@router.get("/sites/{site_id}/maps/compare", dependencies=[Depends(VIEWER)])
def compare_versions(
    site_id: Id,
    session: SessionDep,
    a: Annotated[Id, Query(description="The earlier map version.")],
    b: Annotated[Id, Query(description="The later map version.")],
) -> MapCompareRead:
    """How far every mapping frame moved from version ``a`` to version ``b`` (metres)."""
    return MapCompareRead(
        **map_views.compare_versions(session, _version(session, site_id, a), _version(session, site_id, b))
    )


@router.get("/sites/{site_id}/maps/{version}", dependencies=[Depends(VIEWER)])
def get_version(site_id: Id, version: Id, session: SessionDep) -> MapVersionDetail:
    """One map version: build parameters and figures, row counts, residual mean and maximum."""
    record = _version(session, site_id, version)
    return MapVersionDetail(
        **MapVersionRead.model_validate(record).model_dump(),
        params=record.params,
        **map_views.version_counts(session, record),
    )


@router.get("/sites/{site_id}/maps/{version}/poses", dependencies=[Depends(VIEWER)])
def get_poses(
    site_id: Id,
    version: Id,
    session: SessionDep,
    offset: Annotated[Count, Query()] = 0,
    limit: Annotated[int, Query(ge=1, le=1_000_000)] = 100_000,
) -> PoseArrays:
    """A page of optimised poses as parallel arrays (drive then frame order)."""
    return PoseArrays(**map_views.pose_arrays(session, _version(session, site_id, version), offset, limit))


@router.get("/sites/{site_id}/maps/{version}/closures", dependencies=[Depends(VIEWER)])
def get_closures(site_id: Id, version: Id, session: SessionDep) -> list[ClosureRead]:
    """The loop closures found in the build, with their SAD score and whether the optimiser kept them."""
    rows = map_views.closure_rows(session, _version(session, site_id, version))
    return [ClosureRead(**r) for r in rows]


@router.get("/sites/{site_id}/maps/{version}/nodes", dependencies=[Depends(VIEWER)])
def get_nodes(site_id: Id, version: Id, session: SessionDep, storage: StorageDep) -> NodeArrays:
    """The topological map: node centres and edges."""
    return NodeArrays(**map_views.node_arrays(session, storage.blobs, _version(session, site_id, version)))


@router.get("/sites/{site_id}/maps/{version}/residuals", dependencies=[Depends(VIEWER)])
def get_residuals(site_id: Id, version: Id, session: SessionDep) -> list[ResidualRead]:
    """Grounding residuals (optimised minus surveyed) of the groundings the build used, largest first."""
    rows = residuals.residual_rows(session, _version(session, site_id, version))
    return [ResidualRead(**vars(r)) for r in rows]


@router.get("/sites/{site_id}/maps/{version}/residuals/summary", dependencies=[Depends(VIEWER)])
def get_residual_summary(site_id: Id, version: Id, session: SessionDep) -> ResidualSummaryRead:
    """RMS, mean and max grounding residual (metres) per drive and overall, over the groundings used."""
    summary = residuals.residual_summary(session, _version(session, site_id, version))
    return ResidualSummaryRead.model_validate(summary)


@router.get(
    "/sites/{site_id}/maps/{version}/residuals.csv",
    dependencies=[Depends(VIEWER)],
    response_class=Response,
    responses={200: {"content": {"text/csv": {}}}},
)
def get_residuals_csv(site_id: Id, version: Id, session: SessionDep) -> Response:
    """The residuals as CSV: ``drive,frame,station,x,y,residual_m,enabled``."""
    record = _version(session, site_id, version)
    site = site_by_id(session, site_id)
    return Response(
        residuals.residuals_csv(session, record),
        media_type="text/csv",
        headers={"Content-Disposition": attachment(f"{site.name}-map-{record.version}-residuals.csv")},
    )


@router.delete(
    "/sites/{site_id}/maps/{version}", status_code=status.HTTP_204_NO_CONTENT, dependencies=[Depends(ADMIN)]
)
def delete_version(site_id: Id, version: Id, session: SessionDep, storage: StorageDep) -> None:
    """Delete a map version with its poses, closures, residuals and nodes."""
    candidates = deletion.delete_map_version(session, _version(session, site_id, version))
    session.commit()
    deletion.delete_unreferenced_blobs(storage, candidates)
