"""Request and response bodies of the access routes: login, users, vehicles, frames and positions."""

from __future__ import annotations

from datetime import datetime
from typing import Annotated, Literal

from annotated_types import Ge, Le
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter

from driftmap.api.deps import Role
from driftmap.api.input_types import Finite, Id, Name, NewPassword, Password
from driftmap.live.start import MAX_START_RADIUS_M
from driftmap.services.positions import PositionView


class LoginRequest(BaseModel):
    username: str
    password: Password


class TokenRead(BaseModel):
    access_token: str
    token_type: str = "bearer"
    expires_in: int
    """Seconds until the token expires."""


class Me(BaseModel):
    kind: str
    """``user`` (or ``vehicle`` for a vehicle token, which only ever sees its own record)."""
    id: int
    name: str
    role: Role | None


class UserCreate(BaseModel):
    username: str = Field(min_length=1, max_length=100)
    password: NewPassword
    role: Role


class UserUpdate(BaseModel):
    """Any change revokes the user's login tokens."""

    role: Role | None = None
    password: NewPassword | None = None
    """A new password (an admin's reset)."""
    disabled: bool | None = None
    """True disables the user (no login, tokens revoked), False enables again."""


class UserRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    username: str
    role: Role
    created_at: datetime
    disabled_at: datetime | None = None
    """When the user was disabled; None for an active user."""


class PasswordChange(BaseModel):
    """A user's own password change."""

    current_password: Password
    new_password: NewPassword


class VehicleCreate(BaseModel):
    name: Name
    site_id: Id


class VehicleRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    site_id: int
    created_at: datetime
    token_rotated_at: datetime
    has_camera: bool = False
    """The vehicle has a calibrated camera (``/api/vehicles/{id}/camera``): its frames carry odometry."""


class CameraLens(BaseModel):
    """A camera block's ``lens`` (formats.md): the model, intrinsics and distortion."""

    model: Literal["pinhole", "fisheye"]
    """``pinhole`` (radial-tangential distortion) or ``fisheye`` (equidistant)."""
    K: list[list[float]]
    """3x3 intrinsic matrix, pixels."""
    distortion: list[float]
    """Distortion coefficients: pinhole k1, k2, p1, p2[, k3...]; fisheye k1..k4."""


class VehicleCamera(BaseModel):
    """A vehicle camera's calibration: the ``camera`` block of drive.json (formats.md), same keys and rules."""

    width: int
    """Frame width, pixels."""
    height: int
    """Frame height, pixels."""
    ground_roi: list[int]
    """``[x, y, w, h]`` pixel rectangle of the frame that shows the floor."""
    k_x: float
    """Metres per pixel of image shift in x inside the ROI."""
    k_y: float
    """Metres per pixel of image shift in y inside the ROI."""
    y_c: float
    """Metres from the rear axle to the camera."""
    y_h: float
    """Metres from the camera to the floor point at the ROI centre."""
    forward_sign: int
    """1 when image content moves down as the vehicle drives forward, else -1."""
    ground_homography: list[list[float]] | None
    """Optional 3x3 map from pixel (u, v, 1) to the floor point in the vehicle frame, metres (null: none)."""
    lens: CameraLens | None = None
    """The lens model (``driftmap-drive/2``); null: an ideal pinhole without distortion."""


class StartRequest(BaseModel):
    """A vehicle's known position (survey frame), to seed its live localiser."""

    x: Finite
    """Survey-frame metres (east)."""
    y: Finite
    """Survey-frame metres (north)."""
    radius_m: Annotated[Finite, Ge(0.0), Le(MAX_START_RADIUS_M)] = 10.0
    """How sure the start is, metres (0-200): the belief covers the map's nodes within this of the nearest."""


class StartRead(BaseModel):
    """A seeded known start: the next frame of the vehicle is localised from it."""

    vehicle_id: int
    x: float
    y: float
    radius_m: float
    node: int
    """The map node nearest to the start, where the belief is centred."""
    map_version: int
    """The site's map version the start was seeded on (its latest)."""


class VehicleWithToken(VehicleRead):
    token: str
    """The vehicle's API token: shown once, stored only as a hash."""


class CameraCheck(BaseModel):
    """The obscured-camera judgement after a frame, over the vehicle's recent frames (None: not judged)."""

    obscured: bool | None = None
    """The camera looks obscured: dust or water on the lens, or a covered lens."""
    obscured_reason: str | None = None
    """``dust``, ``water`` or ``covered`` when obscured."""
    salient: float | None = None
    """Smoothed SESAME salient fraction of the frames, 0-1 (low: a bland, covered view)."""
    sharpness: float | None = None
    """Smoothed variance of the Laplacian, grey levels squared."""
    speckle: float | None = None
    """Smoothed fraction of isolated outlier pixels, 0-1 (high: dust)."""
    flat_area: float | None = None
    """Fraction of the image that stayed without detail over the last seconds, 0-1 (a water drop)."""


class FrameEstimate(CameraCheck):
    """The answer to one posted frame.

    ``status`` is ``processed`` (the estimate fields are set), ``skipped`` (a newer frame of the vehicle
    arrived while this one waited: dropped on purpose under overload) or ``out_of_order`` (its ``t`` was not
    after the vehicle's last accepted frame). The counts are the vehicle's totals.
    """

    model_config = ConfigDict(from_attributes=True)

    vehicle_id: int
    t: float
    status: str
    node: int | None = None
    """The map node the localiser believes the vehicle is at (eq. 11)."""
    x: float | None = None
    """Survey-frame metres (east) of the vehicle's estimated position (continuous, not a node centre)."""
    y: float | None = None
    """Survey-frame metres (north) of the vehicle's estimated position."""
    yaw: float | None = None
    """Heading, radians counter-clockwise from +x (east); null when unknown."""
    speed_mps: float | None = None
    """Speed from the camera odometry, metres per second (negative: reversing); null when not measured."""
    moving: bool | None = None
    """Whether the vehicle is moving (null when the frame was not processed)."""
    odometry: bool = False
    """This frame's motion came from the vehicle camera's odometry (always false without a camera)."""
    confidence: float | None = None
    """The calibrated probability, 0-1, that the position is right."""
    matched: bool | None = None
    """The confidence is at least the match threshold and the localiser is not lost."""
    lost: bool | None = None
    """The localiser's lost test failed on this frame and the ones before it (3 in a row by default)."""
    map_version: int | None = None
    seq: int | None = None
    """Sequence number of the stored position (for ``/api/live?since=``)."""
    processed: int
    skipped: int
    out_of_order: int
    ms: float | None = None
    """Localiser step time, milliseconds."""


class PositionRead(CameraCheck):
    model_config = ConfigDict(from_attributes=True)

    seq: int
    vehicle_id: int
    vehicle: str
    site_id: int
    t: float
    """The frame's time on the vehicle's clock, seconds."""
    node: int
    """The map node the localiser believed the vehicle was at."""
    x: float
    """Survey-frame metres (east) of the estimated position (continuous, not a node centre)."""
    y: float
    """Survey-frame metres (north) of the estimated position."""
    yaw: float | None
    """Heading, radians counter-clockwise from +x (east); null when unknown."""
    speed_mps: float | None = None
    """Speed from the camera odometry, metres per second (negative: reversing); null when not measured."""
    moving: bool | None = None
    """Whether the vehicle was moving (null on positions stored before this was recorded)."""
    odometry: bool = False
    """This frame's motion came from the vehicle camera's odometry."""
    confidence: float
    """The calibrated probability, 0-1, that the position is right."""
    matched: bool
    """The confidence is at least the match threshold and the localiser is not lost."""
    lost: bool
    """The localiser's lost test failed on this frame and the ones before it."""
    map_version: int | None
    received_at: datetime


_POSITION_VIEWS: TypeAdapter[list[PositionView]] = TypeAdapter(list[PositionView])


def position_list_json(views: list[PositionView]) -> bytes:
    """``views`` as the JSON body of a ``list[PositionRead]``, encoded straight from the views.

    The views come from the database's typed columns, so validating each as a ``PositionRead`` first (what a
    route returning models does) would check nothing new, at several times the cost of encoding them: an
    hour of one vehicle is 36,000 positions (``bench/bench_history.py --database postgresql``).
    """
    return _POSITION_VIEWS.dump_json(views)


class VehicleLatestRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    vehicle_id: int
    vehicle: str
    site_id: int
    stale: bool
    """No position for longer than the server's ``stale_after_s`` (or none yet)."""
    position: PositionRead | None


class LiveStateRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    vehicle_id: int
    map_version_id: int | None
    last_t_s: float | None
    processed: int
    skipped: int
    out_of_order: int
    updated_at: datetime
