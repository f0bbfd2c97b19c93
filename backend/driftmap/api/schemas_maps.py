"""Request and response bodies of map versions: builds, poses, closures, nodes, residuals, comparisons.

Big maps are served as parallel arrays (``...Arrays``), one page at a time, rather than lists of objects.
"""

from __future__ import annotations

from datetime import datetime
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field


class MapBuildCreate(BaseModel):
    """Start a ``map.build`` job of the site's mapping drives and groundings."""

    preset: Literal["paper", "fast"] = "paper"
    full: bool = Field(
        default=False,
        description="Prepare every drive's odometry again and search loop closures afresh instead of reusing "
        "what earlier builds kept for drives that did not change (the version's stats count segments_reused "
        "and segments_prepared, loop_queries_reused and loop_queries_scored, database_pairs_reused and "
        "database_pairs_scored).",
    )


class MapVersionRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    id: int
    site_id: int
    version: int
    stats: dict[str, Any]
    created_by: str
    created_at: datetime


class MapVersionDetail(MapVersionRead):
    params: dict[str, Any]
    poses: int
    closures: int
    closures_accepted: int
    nodes: int
    residuals: int
    residual_mean_m: float | None
    residual_max_m: float | None


class PoseArrays(BaseModel):
    """Optimised poses of a page of mapping frames, drive then frame order (metres, radians)."""

    total: int
    offset: int
    limit: int
    drive_id: list[int]
    frame: list[int]
    x_m: list[float]
    y_m: list[float]
    yaw_rad: list[float]


class ClosureRead(BaseModel):
    drive_a: int
    frame_a: int
    drive_b: int
    frame_b: int
    d_score: float
    accepted: bool
    chi2: float


class NodeArrays(BaseModel):
    """The topological map: node centres (metres) and the node pairs driven between directly."""

    node: list[int]
    x_m: list[float]
    y_m: list[float]
    edges: list[tuple[int, int]]


class ResidualRead(BaseModel):
    drive: str
    frame: int
    surveyed_x_m: float
    surveyed_y_m: float
    dx_m: float
    dy_m: float
    distance_m: float
    grounding_id: int | None = Field(default=None, description="The grounding; null when deleted since.")
    station: str | None = None
    enabled: bool | None = Field(default=None, description="Whether the grounding is enabled now.")


class ResidualStatsRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    count: int
    rms_m: float = Field(description="Root mean square residual, metres.")
    mean_m: float
    max_m: float


class DriveResidualStatsRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    drive: str
    stats: ResidualStatsRead


class ResidualSummaryRead(BaseModel):
    model_config = ConfigDict(from_attributes=True)

    version: int
    overall: ResidualStatsRead
    drives: list[DriveResidualStatsRead]


class DriveDisplacement(BaseModel):
    drive_id: int
    drive: str
    frames: int
    mean_m: float
    max_m: float


class MapCompareRead(BaseModel):
    """How far every frame moved between two versions (frames present in both), metres."""

    version_a: int
    version_b: int
    frames: int
    only_in_a: int
    only_in_b: int
    mean_m: float | None
    median_m: float | None
    p95_m: float | None
    max_m: float | None
    per_drive: list[DriveDisplacement]
