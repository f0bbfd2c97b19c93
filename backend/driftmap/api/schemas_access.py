"""Request and response bodies of the access routes: login, users, vehicles, frames and positions."""

from __future__ import annotations

from datetime import datetime

from pydantic import BaseModel, ConfigDict, Field

from driftmap.api.deps import Role


class LoginRequest(BaseModel):
    username: str
    password: str


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
    password: str
    role: Role


class UserUpdate(BaseModel):
    role: Role | None = None
    password: str | None = None


class UserRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    username: str
    role: Role
    created_at: datetime


class VehicleCreate(BaseModel):
    name: str = Field(min_length=1, max_length=200)
    site_id: int


class VehicleRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    site_id: int
    created_at: datetime
    token_rotated_at: datetime


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
    x: float | None = None
    """Survey-frame metres (east) of the node centre."""
    y: float | None = None
    """Survey-frame metres (north) of the node centre."""
    confidence: float | None = None
    """The HMM belief of the chosen node, 0-1."""
    matched: bool | None = None
    """Eq. 12 place match: the confidence is at least X_thresh and the localiser is not lost."""
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
    x: float
    y: float
    yaw: float | None
    confidence: float
    matched: bool
    lost: bool
    map_version: int | None
    received_at: datetime


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
