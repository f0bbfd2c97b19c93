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
