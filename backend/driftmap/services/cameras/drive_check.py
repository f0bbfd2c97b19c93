"""A camera checked against a drive: the floor scale on a straight drive over a measured distance, and the
mounting (``forward_sign``, the turn's direction, the lever ``y_c``) on a drive that turns.

The checks dead-reckon the drive with the camera (:mod:`driftmap.core.odometry.scale_check`,
:mod:`driftmap.core.odometry.turn_check`) and give the camera as the check corrects it. ``driftmap camera
check`` runs them on a drive folder's frames, ``POST /api/drives/{id}/camera-check`` on a stored drive's
(:func:`check_stored_drive`, at most :data:`MAX_CHECK_FRAMES` frames: a check runs while the request waits).
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from sqlalchemy.orm import Session

from driftmap.core.odometry.camera import CameraModel
from driftmap.core.odometry.drive import dead_reckon, match_frames
from driftmap.core.odometry.scale_check import ScaleCheck, check_scale, scale_camera
from driftmap.core.odometry.turn_check import TurnCheck, check_turn, mount_camera
from driftmap.errors import BadInputError
from driftmap.formats.drive_json import camera_to_json, parse_camera_block
from driftmap.services.drives import frame_rows, stored_frames
from driftmap.store.blobs import BlobStore
from driftmap.store.models import Drive

__all__ = [
    "MAX_CHECK_FRAMES",
    "DriveCheck",
    "ScaleCheck",
    "TurnCheck",
    "check_drive_scale",
    "check_drive_turn",
    "check_stored_drive",
]

MAX_CHECK_FRAMES = 3000  # five minutes at 10 Hz: a check drive is short, and the request waits for it


def check_drive_scale(
    frames: Iterable[NDArray[np.uint8]], camera: CameraModel, distance_m: float, *, reverse: bool = False
) -> tuple[ScaleCheck, CameraModel]:
    """Dead-reckon a straight drive over ``distance_m`` metres with ``camera``; the check and the corrected
    camera (floor lengths times the ratio, ``forward_sign`` flipped when the travel came out backwards)."""
    result = check_scale(dead_reckon(frames, camera).wTi, distance_m, reverse=reverse)
    return result, scale_camera(camera, result.ratio, flip_sign=result.sign_wrong)


def check_drive_turn(
    frames: Iterable[NDArray[np.uint8]], camera: CameraModel, turn_rad: float, *, reverse: bool = False
) -> tuple[TurnCheck, CameraModel | None]:
    """Dead-reckon a drive that turns through ``turn_rad`` (+ left) with ``camera``; the check and the camera
    with the mounting found (its lever, ``forward_sign``), or None when the turn came out the wrong way (a
    mirrored ground plane: fit it again)."""
    result = check_turn(match_frames(frames, camera), camera, turn_rad, reverse=reverse)
    return result, None if result.direction_wrong else mount_camera(camera, result)


@dataclass(frozen=True)
class DriveCheck:
    """A check of a stored drive.

    Attributes:
        scale: the scale check (with a distance), else None.
        turn: the turn check (with a turn), else None.
        y_c_m: the checked camera's lever (rear axle to camera), metres.
        camera: the camera block (``docs/formats.md``) as the check corrects it; None when it cannot be
            corrected (a turn that came out the wrong way).
    """

    scale: ScaleCheck | None
    turn: TurnCheck | None
    y_c_m: float
    camera: dict[str, Any] | None


def check_stored_drive(
    session: Session,
    blobs: BlobStore,
    drive: Drive,
    *,
    distance_m: float | None = None,
    turn_deg: float | None = None,
    reverse: bool = False,
    camera: object = None,
) -> DriveCheck:
    """Check a camera against a stored drive: its scale (``distance_m``, a straight drive) or its mounting
    (``turn_deg``, + left, a drive that turns); exactly one of the two.

    Args:
        camera: the camera block to check (validated as a drive's); None: the drive's own.

    Raises:
        BadInputError: neither or both of ``distance_m`` and ``turn_deg`` (field ``distance_m``), a bad
            camera block (``camera.<key>``) or one of another frame size than the drive's (``camera.width``),
            a drive of more than :data:`MAX_CHECK_FRAMES` frames (``drive``), or what the check refuses.
    """
    if (distance_m is None) == (turn_deg is None):
        raise BadInputError(
            "give distance_m (a straight drive) or turn_deg (a drive that turns)", field="distance_m"
        )
    own = parse_camera_block(drive.camera, "", f"drive {drive.name!r}")
    model = own if camera is None else parse_camera_block(camera, "", "request body")
    if (model.width_px, model.height_px) != (own.width_px, own.height_px):
        raise BadInputError(
            f"is {model.width_px}x{model.height_px}, the drive's frames {own.width_px}x{own.height_px}",
            field="camera.width",
        )
    rows = frame_rows(session, drive)
    if len(rows) > MAX_CHECK_FRAMES:
        raise BadInputError(
            f"drive {drive.name!r} has {len(rows)} frames; a check drive has at most {MAX_CHECK_FRAMES}",
            field="drive",
        )
    frames = stored_frames(blobs, [f.blob_sha256 for f in rows])
    if distance_m is not None:
        scale, fixed = check_drive_scale(frames, model, distance_m, reverse=reverse)
        return DriveCheck(scale, None, model.y_c_m, camera_to_json(fixed))
    assert turn_deg is not None
    turn, mounted = check_drive_turn(frames, model, math.radians(turn_deg), reverse=reverse)
    return DriveCheck(None, turn, model.y_c_m, None if mounted is None else camera_to_json(mounted))
