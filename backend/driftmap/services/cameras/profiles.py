"""Camera profiles: named, stored ``camera`` blocks (formats.md) that vehicles can be given.

Profiles are global, not per site: one camera model on one kind of mount is often fitted to vehicles of
several sites. A profile's block is validated exactly as a drive import validates its ``camera`` block and
stored in its canonical form; a bad block names the field (``camera.k_x``) and nothing is stored. Giving a
vehicle a profile copies the block to the vehicle (:func:`assign_profile`): editing the profile later does
not change vehicles already given it.
"""

from __future__ import annotations

import json
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.core.odometry.camera import CameraModel
from driftmap.errors import BadInputError, ConflictError, NotFoundError
from driftmap.formats.bounds import DB_INT_MAX
from driftmap.formats.drive_json import camera_to_json, parse_camera_block
from driftmap.services import vehicles as vehicle_service
from driftmap.store.access_models import Vehicle
from driftmap.store.models import CameraProfile

__all__ = [
    "assign_profile",
    "canonical_camera",
    "create_profile",
    "delete_profile",
    "find_profile",
    "get_profile",
    "list_profiles",
    "profile_camera",
    "update_profile",
]


def canonical_camera(block: object) -> dict[str, Any]:
    """A ``camera`` block validated as a drive import does, in the format's key order.

    Raises:
        BadInputError: the block is not a valid camera block (field ``camera.<key>``).
    """
    return camera_to_json(parse_camera_block(block, "", vehicle_service.CAMERA_SOURCE))


def _clean_name(name: str) -> str:
    name = name.strip()
    if not name:
        raise BadInputError("a camera profile needs a non-empty name", field="name")
    return name


def _ensure_unused(session: Session, name: str, own_id: int | None = None) -> None:
    clash = session.scalar(select(CameraProfile.id).where(CameraProfile.name == name))
    if clash is not None and clash != own_id:
        raise ConflictError(f"a camera profile named {name!r} already exists")


def create_profile(session: Session, name: str, camera: object, description: str = "") -> CameraProfile:
    """A new profile holding the validated ``camera`` block; the name must be unused.

    Raises:
        BadInputError: an empty name or a bad block (nothing is stored).
        ConflictError: the name is taken.
    """
    name = _clean_name(name)
    block = canonical_camera(camera)
    _ensure_unused(session, name)
    profile = CameraProfile(name=name, description=description, camera=block)
    session.add(profile)
    session.flush()
    return profile


def list_profiles(session: Session) -> list[CameraProfile]:
    """Every profile, oldest first."""
    return list(session.scalars(select(CameraProfile).order_by(CameraProfile.id)))


def get_profile(session: Session, profile_id: int) -> CameraProfile:
    """The profile with id ``profile_id``."""
    profile = session.get(CameraProfile, profile_id)
    if profile is None:
        raise NotFoundError(f"no camera profile with id {profile_id}")
    return profile


def find_profile(session: Session, name_or_id: str) -> CameraProfile:
    """The profile called ``name_or_id`` (or with that numeric id)."""
    profile = session.scalar(select(CameraProfile).where(CameraProfile.name == name_or_id.strip()))
    if profile is None and name_or_id.strip().isdigit():
        profile = session.get(CameraProfile, int(name_or_id))
    if profile is None:
        raise NotFoundError(f"no camera profile named {name_or_id!r}")
    return profile


def profile_camera(profile: CameraProfile) -> CameraModel:
    """The profile's block as a :class:`CameraModel` (stored blocks are canonical, so this cannot fail)."""
    return parse_camera_block(profile.camera, json.dumps(profile.camera), f"camera profile {profile.name!r}")


def update_profile(
    session: Session,
    profile: CameraProfile,
    *,
    name: str | None = None,
    description: str | None = None,
    camera: object | None = None,
) -> CameraProfile:
    """Change the given fields of ``profile`` (None: keep); everything is checked before anything changes.

    Raises:
        BadInputError: an empty name or a bad block (the profile stays as it was).
        ConflictError: the new name is another profile's.
    """
    new_name = _clean_name(name) if name is not None else None
    block = canonical_camera(camera) if camera is not None else None
    if new_name is not None:
        _ensure_unused(session, new_name, profile.id)
        profile.name = new_name
    if description is not None:
        profile.description = description
    if block is not None:
        profile.camera = block
    session.flush()
    return profile


def delete_profile(session: Session, profile: CameraProfile) -> None:
    """Remove ``profile`` (vehicles given it keep their copy of its block)."""
    session.delete(profile)
    session.flush()


def assign_profile(session: Session, vehicle: Vehicle, profile_id: object) -> dict[str, Any]:
    """Give ``vehicle`` the camera block of profile ``profile_id``; returns the vehicle's stored block.

    Raises:
        BadInputError: ``profile_id`` is not a positive integer (field ``profile``).
        NotFoundError: no such profile.
    """
    if isinstance(profile_id, bool) or not isinstance(profile_id, int) or not 1 <= profile_id <= DB_INT_MAX:
        raise BadInputError(f"must be a camera profile id, found {profile_id!r}", field="profile")
    profile = get_profile(session, profile_id)
    return vehicle_service.set_camera(session, vehicle, profile.camera)
