"""Vehicles of a site and their API tokens (returned once, stored as a SHA-256)."""

from __future__ import annotations

from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.errors import BadInputError, ConflictError, NotFoundError
from driftmap.services.security import new_vehicle_token, token_sha256
from driftmap.store.access_models import Vehicle
from driftmap.store.models import Site, utc_now


def create_vehicle(session: Session, name: str, site_id: int) -> tuple[Vehicle, str]:
    """A new vehicle of site ``site_id`` and its token (the only time the token is known)."""
    name = name.strip()
    if not name:
        raise BadInputError("a vehicle needs a non-empty name", field="name")
    site = session.get(Site, site_id)
    if site is None:
        raise NotFoundError(f"no site with id {site_id}")
    clash = select(Vehicle.id).where(Vehicle.site_id == site_id, Vehicle.name == name)
    if session.scalar(clash) is not None:
        raise ConflictError(f"site {site.name!r} already has a vehicle named {name!r}")
    vehicle = Vehicle(site_id=site_id, name=name, token_sha256="")
    session.add(vehicle)
    session.flush()
    return vehicle, rotate_token(session, vehicle)


def rotate_token(session: Session, vehicle: Vehicle) -> str:
    """A new token for ``vehicle``; the old one stops working at once."""
    token = new_vehicle_token(vehicle.id)
    vehicle.token_sha256 = token_sha256(token)
    vehicle.token_rotated_at = utc_now()
    session.flush()
    return token


def get_vehicle(session: Session, vehicle_id: int) -> Vehicle:
    """The vehicle with id ``vehicle_id``."""
    vehicle = session.get(Vehicle, vehicle_id)
    if vehicle is None:
        raise NotFoundError(f"no vehicle with id {vehicle_id}")
    return vehicle


def list_vehicles(session: Session, site_id: int | None = None) -> list[Vehicle]:
    """Every vehicle (of one site when ``site_id`` is given), oldest first."""
    query = select(Vehicle).order_by(Vehicle.id)
    if site_id is not None:
        query = query.where(Vehicle.site_id == site_id)
    return list(session.scalars(query))


def delete_vehicle(session: Session, vehicle: Vehicle) -> None:
    """Remove ``vehicle`` with its position history and live state."""
    session.delete(vehicle)
    session.flush()
