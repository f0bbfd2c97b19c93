"""How well a map version fits its survey control: RMS, mean and max grounding residual per drive and
overall, and the residuals as CSV (``docs/formats.md``).

A version's residuals are those of the groundings it was built with, which were the enabled ones at build
time; a grounding disabled since still shows, with ``enabled`` false, until the next build. Residuals are
distances in metres from the optimised pose of the grounded frame to the surveyed point (survey frame).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.formats.control_csv import ResidualCsvRow, residuals_text
from driftmap.store.models import Drive, Frame, Grounding, MapGroundingResidual, MapVersion


@dataclass(frozen=True)
class ResidualRow:
    """A grounding residual of a map version (optimised minus surveyed, metres), drive and frame named.

    ``grounding_id``, ``station`` and ``enabled`` are the grounding's as it is now (None when it has been
    deleted since the build); the surveyed point is the one the build used.
    """

    drive: str
    frame: int
    surveyed_x_m: float
    surveyed_y_m: float
    dx_m: float
    dy_m: float
    distance_m: float
    grounding_id: int | None = None
    station: str | None = None
    enabled: bool | None = None


def residual_rows(session: Session, version: MapVersion) -> list[ResidualRow]:
    """The grounding residuals of ``version`` (the enabled groundings it was built with), largest first."""
    query = (
        select(
            Drive.name,
            Frame.index,
            MapGroundingResidual.surveyed_x_m,
            MapGroundingResidual.surveyed_y_m,
            MapGroundingResidual.dx_m,
            MapGroundingResidual.dy_m,
            MapGroundingResidual.distance_m,
            MapGroundingResidual.grounding_id,
            Grounding.station,
            Grounding.enabled,
        )
        .join(Frame, MapGroundingResidual.frame_id == Frame.id)
        .join(Drive, Frame.drive_id == Drive.id)
        .outerjoin(Grounding, MapGroundingResidual.grounding_id == Grounding.id)
        .where(MapGroundingResidual.map_version_id == version.id)
        .order_by(MapGroundingResidual.distance_m.desc(), Drive.id, Frame.index)
    )
    return [ResidualRow(*tuple(row)) for row in session.execute(query).all()]


@dataclass(frozen=True)
class ResidualStats:
    """Residual figures over a set of groundings, metres; all zero when ``count`` is 0."""

    count: int
    rms_m: float
    """Root mean square residual, metres."""
    mean_m: float
    max_m: float


@dataclass(frozen=True)
class DriveResidualStats:
    """:class:`ResidualStats` of one drive's groundings."""

    drive: str
    stats: ResidualStats


@dataclass(frozen=True)
class ResidualSummary:
    """A map version's residual figures: overall and per drive (drives by name)."""

    version: int
    overall: ResidualStats
    drives: list[DriveResidualStats]


def residual_stats(distances_m: Sequence[float]) -> ResidualStats:
    """Count, RMS, mean and max of residual distances (metres)."""
    if not distances_m:
        return ResidualStats(count=0, rms_m=0.0, mean_m=0.0, max_m=0.0)
    n = len(distances_m)
    return ResidualStats(
        count=n,
        rms_m=math.sqrt(sum(d * d for d in distances_m) / n),
        mean_m=sum(distances_m) / n,
        max_m=max(distances_m),
    )


def summarise(version: int, rows: Sequence[ResidualRow]) -> ResidualSummary:
    """The summary of a version's residual rows (see :func:`residual_summary`)."""
    by_drive: dict[str, list[float]] = {}
    for row in rows:
        by_drive.setdefault(row.drive, []).append(row.distance_m)
    return ResidualSummary(
        version=version,
        overall=residual_stats([r.distance_m for r in rows]),
        drives=[DriveResidualStats(name, residual_stats(d)) for name, d in sorted(by_drive.items())],
    )


def residual_summary(session: Session, version: MapVersion) -> ResidualSummary:
    """RMS, mean and max residual of ``version`` per drive and overall, over the groundings it was built with
    (the enabled ones)."""
    return summarise(version.version, residual_rows(session, version))


def residuals_csv(session: Session, version: MapVersion) -> str:
    """``version``'s residuals as CSV: ``drive,frame,station,x,y,residual_m,enabled`` (drive, frame order)."""
    rows = sorted(residual_rows(session, version), key=lambda r: (r.drive, r.frame))
    return residuals_text(
        ResidualCsvRow(
            drive=r.drive,
            frame=r.frame,
            station=r.station,
            x_m=r.surveyed_x_m,
            y_m=r.surveyed_y_m,
            residual_m=r.distance_m,
            enabled=r.enabled,
        )
        for r in rows
    )
