"""Request and response bodies of sites, survey maps, drives, frames, groundings and jobs.

Families per resource: ``XCreate`` (request), ``XUpdate`` (partial request), ``XRead`` (response), and
:class:`Page` for paginated lists. Positions are survey-frame metres, times seconds, angles radians.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from datetime import datetime
from typing import Annotated, Any, Generic, Literal, TypeVar

from annotated_types import Ge, Le, Len
from pydantic import BaseModel, ConfigDict, Field, computed_field

from driftmap.api.input_types import CameraSide, Count, Description, Finite, Id, Name, Station
from driftmap.formats.bounds import MAX_CAMERA_SIDE_PX
from driftmap.formats.site_crs import SiteCrs

T = TypeVar("T")
R = TypeVar("R")
DriveKind = Literal["mapping", "localisation"]
MAX_FPS = 10_000.0  # frames per second above any camera's


class Page(BaseModel, Generic[T]):
    """One page of a list: ``items`` from ``offset``, at most ``limit``, of ``total``."""

    items: list[T]
    total: int
    offset: int
    limit: int


def paged(rows: Sequence[R], offset: int, limit: int, read: Callable[[R], T]) -> Page[T]:
    """The page of ``rows`` from ``offset`` (at most ``limit``), each turned into its answer by ``read``."""
    return Page[T](
        items=[read(r) for r in rows[offset : offset + limit]], total=len(rows), offset=offset, limit=limit
    )


class SiteCreate(BaseModel):
    name: Name
    description: Description = ""


class SiteUpdate(BaseModel):
    name: Name | None = None
    description: Description | None = None


class SiteCrsBody(BaseModel):
    """How the site plane sits on the mine grid and on the Earth (docs/formats.md, Site coordinates)."""

    model_config = ConfigDict(extra="forbid")

    epsg: Annotated[int, Ge(1024), Le(999_999)] | None = None
    """EPSG code of the projected CRS (metres) the mine grid is in; None: the grid is not placed on the Earth."""
    false_easting_m: Finite = 0.0
    false_northing_m: Finite = 0.0
    rotation_deg: Finite = 0.0
    """Counter-clockwise angle from the plane's +x to the grid's east, degrees."""
    scale: Annotated[float, Ge(0.5), Le(2.0)] = 1.0


class SiteCrsRead(SiteCrsBody):
    """The site's coordinates as stored, with the EPSG system's PROJ string for converting in the browser."""

    @computed_field  # type: ignore[prop-decorator]
    @property
    def proj4(self) -> str | None:
        """The ``epsg`` system as a PROJ string (proj4js reads it); None without one."""
        return SiteCrs(**self.model_dump(exclude={"proj4"})).proj4()


class SiteRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    name: str
    description: str
    crs: SiteCrsRead | None = None
    """The site's coordinates; None: plane metres only."""
    created_at: datetime


class SiteSimulate(BaseModel):
    """A synthetic site to render and import as a new site (a ``site.simulate`` job)."""

    name: Name
    seed: Annotated[int, Ge(0), Le(2**32 - 1)] = 0
    """Seed of the random layout and rendering (numpy seeds are 32-bit)."""
    size: Literal["tiny", "small", "medium", "large"] = "tiny"
    obscurants: bool = False
    max_frames_per_drive: Annotated[Count, Ge(2)] | None = None


class SurveyMapRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    site_id: int
    filename: str
    dxf_sha256: str
    units: str
    min_x_m: float
    min_y_m: float
    max_x_m: float
    max_y_m: float
    created_at: datetime


class SurveyLayersRead(BaseModel):
    """GeoJSON FeatureCollections per layer, plane metres, simplified to ``tolerance_m``."""

    survey_map_id: int
    tolerance_m: float
    extents: list[float]
    vertices: int
    layers: dict[str, dict[str, Any]]


class CameraBlock(BaseModel):
    """The ``camera`` block of drive.json (formats.md)."""

    model_config = ConfigDict(extra="allow")

    width: CameraSide
    height: CameraSide
    ground_roi: Annotated[list[Annotated[int, Ge(0), Le(MAX_CAMERA_SIDE_PX)]], Len(4, 4)]
    k_x: Finite
    k_y: Finite
    y_c: Finite
    y_h: Finite
    forward_sign: Annotated[int, Ge(-1), Le(1)] = 1
    """1 or -1 (checked with the rest of the block)."""


class DriveCreate(BaseModel):
    """An empty drive whose frames are then posted one by one."""

    name: Name
    kind: DriveKind = "mapping"
    fps: Annotated[Finite, Field(gt=0, le=MAX_FPS)]
    """Frames per second of the camera."""
    camera: CameraBlock


class DriveUpdate(BaseModel):
    name: Name | None = None


class DriveRead(BaseModel):
    id: int
    site_id: int
    name: str
    kind: str
    fps: float
    frame_count: int
    duration_s: float
    grounding_count: int
    has_truth: bool
    source: str
    camera: dict[str, Any]
    created_at: datetime


class FrameRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    drive_id: int
    index: int
    t_s: float
    image_ext: str
    true_x_m: float | None
    true_y_m: float | None
    true_yaw_rad: float | None


class FrameArrays(BaseModel):
    """A page of a drive's frames as parallel arrays (compact for long drives)."""

    drive_id: int
    total: int
    offset: int
    limit: int
    index: list[int]
    t_s: list[float]
    true_x_m: list[float | None]
    true_y_m: list[float | None]


class LocaliseCreate(BaseModel):
    """Localise a stored drive against a map version (a ``drive.localise`` job)."""

    map_version: Id | None = Field(default=None, description="Map version (default: latest).")
    sesame: bool = True
    temporal: bool = True


class GroundingCreate(BaseModel):
    frame: Count = Field(description="Frame number of the drive.")
    x: Finite = Field(description="Surveyed x (east), metres.")
    y: Finite = Field(description="Surveyed y (north), metres.")
    station: Station | None = Field(default=None, description="Survey station id, e.g. STN-104.")
    enabled: bool = Field(default=True, description="Whether map builds use the grounding.")


class GroundingUpdate(BaseModel):
    x: Finite | None = None
    y: Finite | None = None
    station: Station | None = Field(default=None, description="Survey station id; null or empty clears it.")
    enabled: bool | None = Field(default=None, description="Whether map builds use the grounding.")


class GroundingRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    drive_id: int
    drive: str
    frame: int
    x_m: float
    y_m: float
    station: str | None
    enabled: bool
    created_by: str
    residual_m: float | None
    map_version: int | None


class GroundingImportRead(BaseModel):
    drive_id: int
    imported: int


class SiteGroundingImportRead(BaseModel):
    site_id: int
    imported: int


class JobRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    kind: str
    site_id: int | None
    args: dict[str, Any]
    status: str
    progress: float
    stage: str
    error: str | None
    result: dict[str, Any] | None
    attempts: int
    created_by: str
    created_at: datetime
    started_at: datetime | None
    finished_at: datetime | None
    heartbeat_at: datetime | None
    cancel_requested_at: datetime | None
    worker_id: str | None
    parent_id: int | None = None
    """The job this one is a subtask of (``map.drive`` subtasks of a ``map.build``), else None."""
