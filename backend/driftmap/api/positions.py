"""Position history and the latest position of every vehicle (any logged-in user)."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Query, Response

from driftmap.api.deps import VIEWER, SessionDep, SettingsDep
from driftmap.api.input_types import Count, Id, Seconds
from driftmap.api.schemas_access import LiveStateRead, PositionRead, VehicleLatestRead, position_list_json
from driftmap.errors import BadInputError, NotFoundError
from driftmap.services import positions as position_service
from driftmap.services import vehicles as vehicle_service
from driftmap.services.positions import as_utc
from driftmap.store.access_models import VehicleLiveState

router = APIRouter(tags=["positions"], dependencies=[Depends(VIEWER)])


@router.get("/vehicles/{vehicle_id}/positions", response_model=list[PositionRead])
def vehicle_positions(
    vehicle_id: Id,
    session: SessionDep,
    start: Annotated[
        Seconds | None, Query(description="Earliest frame time t, seconds (vehicle clock).")
    ] = None,
    end: Annotated[Seconds | None, Query(description="Latest frame time t, seconds.")] = None,
    limit: Annotated[int, Query(ge=1, le=100000)] = 10000,
) -> Response:
    """A vehicle's position history between ``start`` and ``end``, in time order."""
    vehicle_service.get_vehicle(session, vehicle_id)
    if start is not None and end is not None and end < start:
        raise BadInputError(f"end ({end}) is before start ({start})", field="end")
    views = position_service.history(session, vehicle_id, start, end, limit)
    return Response(position_list_json(views), media_type="application/json")


@router.get("/vehicles/{vehicle_id}/live-state")
def vehicle_live_state(vehicle_id: Id, session: SessionDep) -> LiveStateRead:
    """A vehicle's frame counts: processed, skipped under overload, refused as out of order."""
    vehicle_service.get_vehicle(session, vehicle_id)
    state = session.get(VehicleLiveState, vehicle_id)
    if state is None:
        raise NotFoundError(f"vehicle {vehicle_id} has not posted a frame yet")
    read = LiveStateRead.model_validate(state)
    return read.model_copy(update={"updated_at": as_utc(read.updated_at)})


@router.get("/positions/latest")
def latest_positions(
    session: SessionDep, settings: SettingsDep, site_id: Id | None = None
) -> list[VehicleLatestRead]:
    """Every vehicle's last known position with its ``stale`` flag."""
    rows = position_service.latest(session, settings.stale_after_s, site_id)
    return [VehicleLatestRead.model_validate(r) for r in rows]


@router.get("/positions", response_model=list[PositionRead])
def positions_since(
    session: SessionDep,
    since: Annotated[Count, Query(description="Positions with a higher seq than this.")] = 0,
) -> Response:
    """Every vehicle's positions after sequence number ``since`` (polling clients resume with it)."""
    views = position_service.since(session, since)
    return Response(position_list_json(views), media_type="application/json")
