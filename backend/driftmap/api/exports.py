"""Downloads: a map version and vehicle position history in the export formats (any logged-in user)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Query
from fastapi.responses import Response

from driftmap.api.deps import VIEWER, SessionDep, StorageDep
from driftmap.api.groundings import attachment
from driftmap.api.input_types import Id, Name, Seconds
from driftmap.api.sites import site_by_id
from driftmap.services import exports as export_service
from driftmap.services import maps as map_service
from driftmap.services.exports import MEDIA_TYPES, ExportFile, MapFormat, PositionFormat

router = APIRouter(tags=["exports"], dependencies=[Depends(VIEWER)])


def _download(exported: ExportFile) -> Response:
    return Response(
        exported.text.encode("utf-8"),
        media_type=exported.media_type,
        headers={"Content-Disposition": attachment(exported.filename)},
    )


def _responses(formats: tuple[str, ...]) -> dict[int | str, dict[str, object]]:
    return {200: {"content": {MEDIA_TYPES[f]: {} for f in formats}, "description": "The file."}}


@router.get(
    "/sites/{site_id}/maps/{version}/export",
    response_class=Response,
    responses=_responses(export_service.MAP_FORMATS),
)
def export_map(
    site_id: Id,
    version: Id,
    session: SessionDep,
    storage: StorageDep,
    format: Annotated[MapFormat, Query(description="File format (docs/formats.md, Exports).")],
    drive: Annotated[
        Name | None, Query(description="Only this mapping drive (needed by tum and kitti).")
    ] = None,
    nodes: Annotated[bool, Query(description="DXF: add the NODES layer.")] = False,
    closures: Annotated[bool, Query(description="DXF: add the CLOSURES layers.")] = False,
) -> Response:
    """A map version's optimised poses as a file: CSV, GeoJSON, DXF, KML, TUM, KITTI or the g2o pose graph."""
    site = site_by_id(session, site_id)
    record = map_service.get_map_version(session, site, version)
    exported = export_service.export_map(
        session, storage.blobs, site, record, format, drive=drive, nodes=nodes, closures=closures
    )
    return _download(exported)


@router.get(
    "/sites/{site_id}/positions/export",
    response_class=Response,
    responses=_responses(export_service.POSITION_FORMATS),
)
def export_positions(
    site_id: Id,
    session: SessionDep,
    format: Annotated[PositionFormat, Query(description="File format (docs/formats.md, Exports).")],
    vehicle: Annotated[Name | None, Query(description="Only this vehicle (default: every vehicle).")] = None,
    since: Annotated[
        Seconds | None, Query(description="Earliest frame time t, seconds (vehicle clock).")
    ] = None,
    until: Annotated[
        Seconds | None, Query(description="Latest frame time t, seconds (vehicle clock).")
    ] = None,
) -> Response:
    """The position history of the site's vehicles (or one) between ``since`` and ``until`` as a file."""
    site = site_by_id(session, site_id)
    exported = export_service.export_positions(
        session, site, format, vehicle=vehicle, since_s=since, until_s=until
    )
    return _download(exported)
