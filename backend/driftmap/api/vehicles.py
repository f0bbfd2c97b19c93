"""Vehicles: register (admin; the answer holds the vehicle's token, shown once), list, read, rotate, delete;
their cameras and known starts (surveyors and admins).

``PUT /api/vehicles/{id}/camera`` takes the ``camera`` block of drive.json (formats.md) as the JSON body and
checks it as a drive import does (a bad block is 422 naming the field, e.g. ``camera.k_x``, and the old camera
stays), or ``{"profile": <id>}`` to give the vehicle a copy of a camera profile's block
(``/api/camera-profiles``; 404 for an unknown profile). Changing or deleting the camera restarts the vehicle's
live localisation at its next frame.

``POST /api/vehicles/{id}/start`` seeds the vehicle's live belief at a known position, as ``driftmap localise
--start`` does: 422 naming ``x``, ``y`` or ``radius_m`` for a value that is not finite, a radius outside 0-200
m, or a start more than 50 m from every node of the map; 409 when the site has no map yet. Nothing changes on
an error. A start set is logged as a ``start_known`` event acknowledged by its setter, and pushed to the live
watchers.
"""

from __future__ import annotations

import asyncio
from typing import Annotated, Any

from fastapi import APIRouter, Body, Depends, Request, status

from driftmap.api.deps import (
    ADMIN,
    SURVEYOR,
    VIEWER,
    Principal,
    SessionDep,
    SurveyorDep,
    forget_principals,
)
from driftmap.api.input_types import Id
from driftmap.api.schemas_access import (
    StartRead,
    StartRequest,
    VehicleCamera,
    VehicleCreate,
    VehicleRead,
    VehicleWithToken,
)
from driftmap.errors import NotFoundError
from driftmap.live import start as live_start
from driftmap.live.ingest import LiveService
from driftmap.services import events as event_service
from driftmap.services import vehicles as vehicle_service
from driftmap.services.cameras import profiles as profile_service
from driftmap.services.events import EventChange
from driftmap.store.models import utc_now
from driftmap.store.storage import Storage

router = APIRouter(prefix="/vehicles", tags=["vehicles"])
_CAMERA_BODY = {
    "requestBody": {
        "required": True,
        "content": {
            "application/json": {
                "schema": {
                    "anyOf": [
                        {"$ref": "#/components/schemas/VehicleCamera"},
                        {
                            "title": "CameraProfileRef",
                            "type": "object",
                            "properties": {"profile": {"type": "integer", "minimum": 1}},
                            "required": ["profile"],
                            "additionalProperties": False,
                        },
                    ]
                }
            }
        },
    }
}


def _camera_block(stored: dict[str, Any]) -> VehicleCamera:
    return VehicleCamera.model_validate({"ground_homography": None, "lens": None, **stored})


def _with_token(vehicle: object, token: str) -> VehicleWithToken:
    return VehicleWithToken(**VehicleRead.model_validate(vehicle).model_dump(), token=token)


@router.post("", status_code=status.HTTP_201_CREATED, dependencies=[Depends(ADMIN)])
def create_vehicle(body: VehicleCreate, session: SessionDep) -> VehicleWithToken:
    """Register a vehicle of a site; the response's ``token`` is its API token, shown only now."""
    vehicle, token = vehicle_service.create_vehicle(session, body.name, body.site_id)
    return _with_token(vehicle, token)


@router.get("", dependencies=[Depends(VIEWER)])
def list_vehicles(session: SessionDep, site_id: Id | None = None) -> list[VehicleRead]:
    """Every vehicle, or those of one site."""
    return [VehicleRead.model_validate(v) for v in vehicle_service.list_vehicles(session, site_id)]


@router.get("/{vehicle_id}", dependencies=[Depends(VIEWER)])
def get_vehicle(vehicle_id: Id, session: SessionDep) -> VehicleRead:
    """One vehicle."""
    return VehicleRead.model_validate(vehicle_service.get_vehicle(session, vehicle_id))


@router.post("/{vehicle_id}/token", dependencies=[Depends(ADMIN)])
def rotate_token(vehicle_id: Id, session: SessionDep, request: Request) -> VehicleWithToken:
    """Give the vehicle a new token; the old one stops working."""
    vehicle = vehicle_service.get_vehicle(session, vehicle_id)
    token = vehicle_service.rotate_token(session, vehicle)
    session.commit()
    forget_principals(request)
    return _with_token(vehicle, token)


@router.delete("/{vehicle_id}", status_code=status.HTTP_204_NO_CONTENT, dependencies=[Depends(ADMIN)])
def delete_vehicle(vehicle_id: Id, session: SessionDep, request: Request) -> None:
    """Remove a vehicle with its position history."""
    vehicle_service.delete_vehicle(session, vehicle_service.get_vehicle(session, vehicle_id))
    session.commit()
    forget_principals(request)


@router.get("/{vehicle_id}/camera", dependencies=[Depends(VIEWER)])
def get_camera(vehicle_id: Id, session: SessionDep) -> VehicleCamera:
    """The vehicle's camera block (404 when it has none)."""
    vehicle = vehicle_service.get_vehicle(session, vehicle_id)
    if vehicle.camera is None:
        raise NotFoundError(f"vehicle {vehicle.name!r} has no camera")
    return _camera_block(vehicle.camera)


@router.put("/{vehicle_id}/camera", dependencies=[Depends(SURVEYOR)], openapi_extra=_CAMERA_BODY)
def put_camera(vehicle_id: Id, session: SessionDep, block: Annotated[Any, Body()]) -> VehicleCamera:
    """Set the vehicle's camera (a ``camera`` block or ``{"profile": id}``); live localisation restarts."""
    vehicle = vehicle_service.get_vehicle(session, vehicle_id)
    if isinstance(block, dict) and set(block) == {"profile"}:
        return _camera_block(profile_service.assign_profile(session, vehicle, block["profile"]))
    return _camera_block(vehicle_service.set_camera(session, vehicle, block))


@router.delete(
    "/{vehicle_id}/camera", status_code=status.HTTP_204_NO_CONTENT, dependencies=[Depends(SURVEYOR)]
)
def delete_camera(vehicle_id: Id, session: SessionDep) -> None:
    """Remove the vehicle's camera (404 when it has none); its live localisation restarts."""
    vehicle_service.delete_camera(session, vehicle_service.get_vehicle(session, vehicle_id))


def _seed_start(
    storage: Storage, vehicle_id: int, body: StartRequest, user: Principal
) -> tuple[StartRead, EventChange]:
    with storage.db.session() as session:
        seeded = live_start.seed_known_start(
            session, storage.blobs, vehicle_id, body.x, body.y, body.radius_m
        )
        vehicle = vehicle_service.get_vehicle(session, vehicle_id)
        change = event_service.record_known_start(
            session, vehicle, seeded.x, seeded.y, seeded.radius_m, user.id, user.name, utc_now()
        )
    read = StartRead(
        vehicle_id=seeded.vehicle_id,
        x=seeded.x,
        y=seeded.y,
        radius_m=seeded.radius_m,
        node=seeded.node,
        map_version=seeded.map_version,
    )
    return read, change


@router.post("/{vehicle_id}/start")
async def post_start(vehicle_id: Id, body: StartRequest, request: Request, user: SurveyorDep) -> StartRead:
    """Seed the vehicle's live localisation at a known position on its site's latest map."""
    read, change = await asyncio.to_thread(_seed_start, request.app.state.storage, vehicle_id, body, user)
    live: LiveService = request.app.state.live
    await live.publish_event(change)
    return read
