"""Request and response bodies of camera calibration (``/api/cameras``) and camera profiles
(``/api/camera-profiles``).

Pixels are of the calibrated frame (``width`` x ``height``); floor positions are metres in the camera's look
frame (origin on the floor under the camera, x the way the camera looks, y to its left; formats.md). A
``camera`` block in a request is checked by the service as a drive
import checks it (formats.md), so its errors name ``camera.<key>``.
"""

from __future__ import annotations

import base64
from datetime import datetime
from typing import Annotated, Any

from annotated_types import Ge, Gt, Le, Len
from pydantic import BaseModel, WithJsonSchema

from driftmap.api.input_types import CameraSide, Description, Finite, Name
from driftmap.api.schemas_access import CameraLens, VehicleCamera
from driftmap.formats.bounds import MAX_CAMERA_SIDE_PX
from driftmap.services.cameras.preview import Preview

MAX_GROUND_POINTS = 100  # more floor points than anyone clicks; the degeneracy check is cubic in them
CameraBody = Annotated[
    dict[str, Any],
    WithJsonSchema(
        {
            "type": "object",
            "additionalProperties": True,
            "description": "A camera block with the keys of VehicleCamera (formats.md), checked as a drive "
            "import checks it.",
        }
    ),
]
"""A ``camera`` block in a request: an object for clients (the keys of :class:`VehicleCamera`), checked by the
service so that its errors name ``camera.<key>``."""
Roi = Annotated[list[Annotated[int, Ge(0), Le(MAX_CAMERA_SIDE_PX)]], Len(4, 4)]


class IntrinsicsView(BaseModel):
    """One image the board was found in."""

    name: str
    """The uploaded file's name (``video.mp4#frame 30`` for a frame of a video)."""
    rms_px: float
    """Reprojection RMS of the view, pixels: one far above the others is blurred or mis-detected."""


class IntrinsicsRead(BaseModel):
    """A calibrated lens: the camera block's ``lens``, ``width`` and ``height``, and how well views fit it."""

    lens: CameraLens
    width: int
    """Frame width, pixels."""
    height: int
    """Frame height, pixels."""
    rms_px: float
    """Reprojection RMS over every view, pixels."""
    views: list[IntrinsicsView]
    """The views calibrated, in upload order."""
    skipped: list[str]
    """Names of the images the board was not found in."""


class GroundPoint(BaseModel):
    """A floor mark clicked in a frame and its measured floor position."""

    px: Finite
    """Pixel column of the mark in the recorded (raw) frame."""
    py: Finite
    """Pixel row of the mark in the recorded (raw) frame."""
    x_m: Finite
    """Floor position along the way the camera looks from the floor under it, metres (look frame: for a camera
    looking behind, marks behind the vehicle are positive)."""
    y_m: Finite
    """Floor position to the left of the camera's look, metres (look frame)."""


class GroundRequest(BaseModel):
    """Four or more clicked floor points of one frame; the points are numbered from 1 in errors."""

    points: Annotated[list[GroundPoint], Len(0, MAX_GROUND_POINTS)]
    width: CameraSide
    """Frame width, pixels."""
    height: CameraSide
    """Frame height, pixels."""
    ground_roi: Roi | None = None
    """``[x, y, w, h]`` ground ROI of the undistorted image; null: the points' bounding box."""
    lens: CameraLens | None = None
    """The camera's lens (``POST /api/cameras/intrinsics``); the clicked pixels are undistorted first."""


class GroundRead(BaseModel):
    """The camera block's ground values fitted to the points, and each point's residual."""

    ground_roi: list[int]
    """``[x, y, w, h]`` the scales were taken at, pixels of the undistorted image."""
    k_x: float
    """Metres per pixel of image shift in x at the ROI centre."""
    k_y: float
    """Metres per pixel of image shift in y at the ROI centre."""
    y_h: float
    """Metres from the camera's foot to the floor point at the ROI centre."""
    ground_homography: list[list[float]]
    """3x3 map from undistorted pixel (u, v, 1) to the floor point (x, y, w), look frame, metres."""
    residuals_m: list[float]
    """Per point (in request order), metres between its measured and its fitted floor position."""


class BirdsEyeRead(BaseModel):
    """The floor around the ground ROI's footprint seen from above: x (the way the camera looks) up, y left."""

    png: str
    """The view, a grey PNG, base64; floor the camera does not see is black."""
    width: int
    """Pixels."""
    height: int
    """Pixels."""
    res_m_per_px: float
    """Floor metres per pixel (square pixels, a whole number of millimetres)."""
    floor_from_px: list[list[float]]
    """3x3 map from a view pixel (col, row, 1), pixel centres at integers, to the floor point (x, y, 1), look
    frame, metres."""
    x_range_m: list[float]
    """[bottom, top]: floor x at the view's bottom and top edges, metres."""
    y_range_m: list[float]
    """[right, left]: floor y at the view's right and left edges, metres."""
    footprint_px: list[list[float]]
    """The ground ROI's corners (top-left, top-right, bottom-right, bottom-left of the ROI) in view pixels
    (col, row)."""


class PreviewRead(BaseModel):
    """A frame's undistorted image and, when the camera block has a ground homography, its bird's-eye view."""

    width: int
    """Width of the frame and of its undistorted image, pixels."""
    height: int
    """Height, pixels."""
    undistorted_png: str
    """The ideal pinhole image of the same size and K (the frame itself without a lens), a grey PNG, base64;
    the ground ROI and homography refer to its pixels."""
    birdseye: BirdsEyeRead | None
    """The bird's-eye view, or null without a ground homography."""


class CameraProfileCreate(BaseModel):
    """A named camera block to give vehicles."""

    name: Name
    description: Description = ""
    camera: CameraBody


class CameraProfileUpdate(BaseModel):
    """The fields to change (absent or null: keep)."""

    name: Name | None = None
    description: Description | None = None
    camera: CameraBody | None = None


class CameraProfileRead(BaseModel):
    """A stored camera profile."""

    id: int
    name: str
    description: str
    camera: VehicleCamera
    created_at: datetime
    updated_at: datetime


def profile_read(profile: Any) -> CameraProfileRead:
    """The response body of a stored :class:`~driftmap.store.models.CameraProfile`."""
    return CameraProfileRead(
        id=profile.id,
        name=profile.name,
        description=profile.description,
        camera=VehicleCamera.model_validate({"ground_homography": None, "lens": None, **profile.camera}),
        created_at=profile.created_at,
        updated_at=profile.updated_at,
    )


def preview_read(preview: Preview) -> PreviewRead:
    """The response body of a frame's previews (PNG bytes as base64)."""
    birdseye = None
    if preview.birdseye is not None and preview.birdseye_png is not None:
        view = preview.birdseye
        (x_lo, x_hi), (y_lo, y_hi) = view.ranges_m()
        birdseye = BirdsEyeRead(
            png=base64.b64encode(preview.birdseye_png).decode("ascii"),
            width=int(view.image.shape[1]),
            height=int(view.image.shape[0]),
            res_m_per_px=view.res_m_per_px,
            floor_from_px=view.floor_from_px.tolist(),
            x_range_m=[x_lo, x_hi],
            y_range_m=[y_lo, y_hi],
            footprint_px=view.footprint_px.tolist(),
        )
    return PreviewRead(
        width=preview.width_px,
        height=preview.height_px,
        undistorted_png=base64.b64encode(preview.undistorted_png).decode("ascii"),
        birdseye=birdseye,
    )


class CameraCheckRequest(BaseModel):
    """What to check against a stored drive: its scale or its mounting (give exactly one)."""

    distance_m: Annotated[Finite, Gt(0)] | None = None
    """A straight drive: the distance driven, metres, measured on the floor."""
    turn_deg: Finite | None = None
    """A drive that turns: the turn driven, degrees, + left (counter-clockwise seen from above), at least 20."""
    reverse: bool = False
    """The drive was in reverse."""
    camera: CameraBody | None = None
    """The camera block to check; absent: the drive's own."""


class CameraCheckRead(BaseModel):
    """The outcome of a check and the camera block as it corrects it."""

    travelled_m: float
    """Odometry's travel, metres (+ forward): along the starting heading (scale), summed along the path (turn)."""
    sign_wrong: bool
    """The travel came out the wrong way: ``forward_sign`` is wrong (flipped in ``camera``)."""
    ratio: float | None
    """Scale: measured over odometry's distance; every floor length of the calibration is multiplied by it."""
    turned_deg: float | None
    """Turn: odometry's heading change, degrees, + left."""
    direction_wrong: bool | None
    """Turn: odometry turned the other way: the ground plane is mirrored (``camera`` is null: fit it again)."""
    y_c_m: float
    """The checked camera's lever (rear axle to camera), metres."""
    fitted_y_c_m: float | None
    """Turn: the lever the floor's own rotation determines, metres (null: it does not)."""
    fitted_se_m: float | None
    """Its standard error, metres."""
    turn_y_c_m: float | None
    """Turn: the lever with which odometry turns through ``turn_deg``, metres (null: none within 5 m)."""
    camera: dict[str, Any] | None
    """The camera block as corrected (scale, ``forward_sign``, ``y_c``); null when it cannot be."""
