"""Vehicles: register (admin; the answer holds the vehicle's token, shown once), list, read, rotate, delete."""

from __future__ import annotations

from fastapi import APIRouter, Depends, Request, status

from driftmap.api.deps import ADMIN, VIEWER, SessionDep, forget_principals
from driftmap.api.schemas_access import VehicleCreate, VehicleRead, VehicleWithToken
from driftmap.services import vehicles as vehicle_service

router = APIRouter(prefix="/vehicles", tags=["vehicles"])


def _with_token(vehicle: object, token: str) -> VehicleWithToken:
    return VehicleWithToken(**VehicleRead.model_validate(vehicle).model_dump(), token=token)


@router.post("", status_code=status.HTTP_201_CREATED, dependencies=[Depends(ADMIN)])
def create_vehicle(body: VehicleCreate, session: SessionDep) -> VehicleWithToken:
    """Register a vehicle of a site; the response's ``token`` is its API token, shown only now."""
    vehicle, token = vehicle_service.create_vehicle(session, body.name, body.site_id)
    return _with_token(vehicle, token)


@router.get("", dependencies=[Depends(VIEWER)])
def list_vehicles(session: SessionDep, site_id: int | None = None) -> list[VehicleRead]:
    """Every vehicle, or those of one site."""
    return [VehicleRead.model_validate(v) for v in vehicle_service.list_vehicles(session, site_id)]


@router.get("/{vehicle_id}", dependencies=[Depends(VIEWER)])
def get_vehicle(vehicle_id: int, session: SessionDep) -> VehicleRead:
    """One vehicle."""
    return VehicleRead.model_validate(vehicle_service.get_vehicle(session, vehicle_id))


@router.post("/{vehicle_id}/token", dependencies=[Depends(ADMIN)])
def rotate_token(vehicle_id: int, session: SessionDep, request: Request) -> VehicleWithToken:
    """Give the vehicle a new token; the old one stops working."""
    vehicle = vehicle_service.get_vehicle(session, vehicle_id)
    token = vehicle_service.rotate_token(session, vehicle)
    session.commit()
    forget_principals(request)
    return _with_token(vehicle, token)


@router.delete("/{vehicle_id}", status_code=status.HTTP_204_NO_CONTENT, dependencies=[Depends(ADMIN)])
def delete_vehicle(vehicle_id: int, session: SessionDep, request: Request) -> None:
    """Remove a vehicle with its position history."""
    vehicle_service.delete_vehicle(session, vehicle_service.get_vehicle(session, vehicle_id))
    session.commit()
    forget_principals(request)
