"""Vehicles of a site, their API tokens (returned once, stored as a SHA-256) and their cameras.

A vehicle's camera is the ``camera`` block of drive.json (formats.md), validated exactly as a drive import
validates it and stored in its canonical form. Changing it drops the vehicle's stored localiser state (the
belief and odometry of the old camera), so the next frame starts afresh with the new camera.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.core.odometry.camera import CameraModel
from driftmap.errors import BadInputError, ConflictError, NotFoundError
from driftmap.formats.drive_json import camera_to_json, parse_camera_block
from driftmap.services.security import new_vehicle_token, token_sha256
from driftmap.store.access_models import Vehicle, VehicleLiveState
from driftmap.store.models import Site, utc_now

CAMERA_SOURCE = "request body"  # where a camera block given through the API comes from, in error messages


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


def vehicle_camera(vehicle: Vehicle) -> CameraModel | None:
    """The vehicle's calibrated camera, None when it has none."""
    if vehicle.camera is None:
        return None
    return parse_camera_block(vehicle.camera, "", f"vehicle {vehicle.id} camera")


def set_camera(session: Session, vehicle: Vehicle, block: object) -> dict[str, Any]:
    """Validate a ``camera`` block and store it as ``vehicle``'s camera; returns the stored block.

    Raises:
        BadInputError: the block is not a valid camera block (the field is named ``camera.<key>``); nothing
            is changed.
    """
    stored = camera_to_json(parse_camera_block(block, "", CAMERA_SOURCE))
    if vehicle.camera == stored:
        return stored  # the same camera: the live state stays valid
    vehicle.camera = stored
    _drop_live_state(session, vehicle.id)
    session.flush()
    return stored


def delete_camera(session: Session, vehicle: Vehicle) -> None:
    """Remove ``vehicle``'s camera (NotFoundError when it has none)."""
    if vehicle.camera is None:
        raise NotFoundError(f"vehicle {vehicle.name!r} has no camera")
    vehicle.camera = None
    _drop_live_state(session, vehicle.id)
    session.flush()


def _drop_live_state(session: Session, vehicle_id: int) -> None:
    """Forget the vehicle's stored localiser state and bump its revision (the counts stay): every server
    process rebuilds its localiser at the vehicle's next frame."""
    state = session.get(VehicleLiveState, vehicle_id)
    if state is not None:
        state.state_npz = None
        state.updated_at = utc_now()  # an update even when there was no state: the revision moves on


def check_frame_size(vehicle: Vehicle, frame: NDArray[np.uint8]) -> None:
    """A vehicle with a camera block takes only frames of its camera's width and height (pixels).

    Raises:
        BadInputError: another size, naming the request body.
    """
    if vehicle.camera is None:
        return
    width_px, height_px = int(vehicle.camera["width"]), int(vehicle.camera["height"])
    if (frame.shape[1], frame.shape[0]) != (width_px, height_px):
        raise BadInputError(
            f"frame is {frame.shape[1]}x{frame.shape[0]} pixels but vehicle {vehicle.id}'s camera says "
            f"{width_px}x{height_px}",
            field="body",
        )
