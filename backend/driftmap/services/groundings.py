"""Groundings: a surveyor's statement that a frame of a mapping drive was taken at a surveyed point.

Create, move, enable or disable, name the survey station of, and delete single groundings; list a site's
groundings with their residuals in the latest map version; import and export a drive's groundings in the
``groundings.csv`` format of formats.md, or a whole site's as its control file (``drive,frame,station,x,y,
enabled``). An import replaces the drive's (or site's) groundings as a whole, after the whole file has been
checked (errors name the line and the field). Map builds use enabled groundings only.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from driftmap.errors import BadInputError, ConflictError, NotFoundError
from driftmap.formats.control_csv import control_text, parse_control_rows
from driftmap.formats.csv_exports import groundings_text, parse_groundings_rows
from driftmap.formats.records import STATION_MAX_CHARS, GroundingRow, SiteGroundingRow
from driftmap.formats.tables import decode_text
from driftmap.services.drives import grounding_rows
from driftmap.store.models import Drive, Frame, Grounding, MapGroundingResidual
from driftmap.store.queries import latest_map_version


@dataclass(frozen=True)
class GroundingView:
    """One grounding with its drive and frame named and its residual in the latest map (when any)."""

    id: int
    drive_id: int
    drive: str
    frame: int
    x_m: float
    y_m: float
    station: str | None
    """Survey station id, when the point is one."""
    enabled: bool
    """Whether map builds use the grounding."""
    created_by: str
    residual_m: float | None
    """Distance from the optimised pose to the surveyed point in the latest map version, metres."""
    map_version: int | None
    """The map version of ``residual_m``; None when the grounding is newer than the latest build."""


def _check_point(x_m: float, y_m: float) -> None:
    for name, value in (("x", x_m), ("y", y_m)):
        if not math.isfinite(value):
            raise BadInputError(f"{name} must be a finite number of metres", field=name)


def _clean_station(station: str | None) -> str | None:
    """A station id stripped of surrounding blanks; empty gives None."""
    if station is None or not station.strip():
        return None
    value = station.strip()
    if len(value) > STATION_MAX_CHARS or any(ord(c) < 32 or ord(c) == 127 for c in value):
        raise BadInputError(
            f"station must be at most {STATION_MAX_CHARS} characters without control characters",
            field="station",
        )
    return value


def get_grounding(session: Session, grounding_id: int) -> Grounding:
    grounding = session.get(Grounding, grounding_id)
    if grounding is None:
        raise NotFoundError(f"no grounding with id {grounding_id}")
    return grounding


def _frame_of(session: Session, drive: Drive, index: int) -> Frame:
    frame = session.scalar(select(Frame).where(Frame.drive_id == drive.id, Frame.index == index))
    if frame is None:
        raise NotFoundError(f"drive {drive.name!r} has no frame {index}")
    return frame


def create_grounding(
    session: Session,
    drive: Drive,
    frame_index: int,
    x_m: float,
    y_m: float,
    created_by: str,
    *,
    station: str | None = None,
    enabled: bool = True,
) -> Grounding:
    """Ground frame ``frame_index`` of ``drive`` at survey point (x_m, y_m) metres; one grounding per frame."""
    _check_point(x_m, y_m)
    station = _clean_station(station)
    if drive.kind != "mapping":
        raise BadInputError(f"drive {drive.name!r} is a {drive.kind} drive; only mapping drives are grounded")
    frame = _frame_of(session, drive, frame_index)
    if session.scalar(select(Grounding.id).where(Grounding.frame_id == frame.id)) is not None:
        raise ConflictError(f"frame {frame_index} of drive {drive.name!r} is already grounded")
    grounding = Grounding(
        drive_id=drive.id,
        frame_id=frame.id,
        x_m=x_m,
        y_m=y_m,
        station=station,
        enabled=enabled,
        created_by=created_by,
    )
    session.add(grounding)
    session.flush()
    return grounding


def update_grounding(
    session: Session,
    grounding: Grounding,
    *,
    x_m: float | None = None,
    y_m: float | None = None,
    enabled: bool | None = None,
    station: str | None = None,
) -> Grounding:
    """Move a grounding's surveyed point (metres), enable or disable it, or set its station.

    None leaves a value as it is; ``station=""`` clears the station.
    """
    new_x = grounding.x_m if x_m is None else x_m
    new_y = grounding.y_m if y_m is None else y_m
    _check_point(new_x, new_y)
    grounding.x_m, grounding.y_m = new_x, new_y
    if enabled is not None:
        grounding.enabled = enabled
    if station is not None:
        grounding.station = _clean_station(station)
    session.flush()
    return grounding


def delete_grounding(session: Session, grounding: Grounding) -> None:
    """Remove a grounding (residuals of earlier map versions keep their numbers)."""
    session.delete(grounding)
    session.flush()


def list_groundings(
    session: Session, site_id: int, drive_id: int | None = None, offset: int = 0, limit: int = 1000
) -> tuple[list[GroundingView], int]:
    """A site's groundings (or one drive's) in drive then frame order, with latest-map residuals."""
    version = latest_map_version(session, site_id)
    residuals: dict[int, float] = {}
    if version is not None:
        residuals = {
            gid: dist
            for gid, dist in session.execute(
                select(MapGroundingResidual.grounding_id, MapGroundingResidual.distance_m).where(
                    MapGroundingResidual.map_version_id == version.id
                )
            )
            if gid is not None
        }
    query = (
        select(Grounding, Drive.name, Frame.index)
        .join(Drive, Grounding.drive_id == Drive.id)
        .join(Frame, Grounding.frame_id == Frame.id)
        .where(Drive.site_id == site_id)
        .order_by(Drive.id, Frame.index)
    )
    if drive_id is not None:
        query = query.where(Drive.id == drive_id)
    rows = session.execute(query).all()
    views = [
        GroundingView(
            id=g.id,
            drive_id=g.drive_id,
            drive=name,
            frame=index,
            x_m=g.x_m,
            y_m=g.y_m,
            station=g.station,
            enabled=g.enabled,
            created_by=g.created_by,
            residual_m=residuals.get(g.id),
            map_version=version.version if version is not None and g.id in residuals else None,
        )
        for g, name, index in rows
    ]
    return views[offset : offset + limit], len(views)


def export_csv(session: Session, drive: Drive) -> str:
    """The drive's groundings as ``groundings.csv`` text (header ``frame,x,y``, frame order)."""
    return groundings_text(grounding_rows(session, drive))


def import_csv(session: Session, drive: Drive, data: bytes, filename: str, created_by: str) -> int:
    """Replace the drive's groundings with those of a ``groundings.csv``; returns how many were stored.

    Raises:
        BadInputError: naming ``filename``, the line and the field (bad header, bad number, duplicate
            frame, or a frame the drive does not have). Nothing is changed then.
    """
    if drive.kind != "mapping":
        raise BadInputError(f"drive {drive.name!r} is a {drive.kind} drive; only mapping drives are grounded")
    rows: list[tuple[int, GroundingRow]] = parse_groundings_rows(decode_text(data, filename), filename)
    frame_ids = dict(session.execute(select(Frame.index, Frame.id).where(Frame.drive_id == drive.id)).all())
    for line, row in rows:
        if row.frame not in frame_ids:
            raise BadInputError(
                f"drive {drive.name!r} has no frame {row.frame}", file=filename, line=line, field="frame"
            )
    session.execute(delete(Grounding).where(Grounding.drive_id == drive.id))
    session.add_all(
        Grounding(
            drive_id=drive.id,
            frame_id=frame_ids[r.frame],
            x_m=r.x_m,
            y_m=r.y_m,
            station=r.station,
            enabled=r.enabled,
            created_by=created_by,
        )
        for _line, r in rows
    )
    session.flush()
    return len(rows)


def export_site_csv(session: Session, site_id: int) -> str:
    """The site's groundings as its control file (``drive,frame,station,x,y,enabled``; drive, frame order)."""
    query = (
        select(Drive.name, Frame.index, Grounding.station, Grounding.x_m, Grounding.y_m, Grounding.enabled)
        .join(Drive, Grounding.drive_id == Drive.id)
        .join(Frame, Grounding.frame_id == Frame.id)
        .where(Drive.site_id == site_id)
        .order_by(Drive.id, Frame.index)
    )
    return control_text(SiteGroundingRow(*row) for row in session.execute(query).all())


def import_site_csv(session: Session, site_id: int, data: bytes, filename: str, created_by: str) -> int:
    """Replace all the site's groundings with those of a control file; returns how many were stored.

    Raises:
        BadInputError: naming ``filename``, the line and the field: a bad header or cell, a drive the site
            has no mapping drive of that name, a frame the drive does not have, a non-finite coordinate, a
            bad enabled value, a drive and frame twice. Nothing is changed then.
    """
    rows = parse_control_rows(decode_text(data, filename), filename)
    drives = {d.name: d for d in session.scalars(select(Drive).where(Drive.site_id == site_id))}
    frame_ids: dict[int, dict[int, int]] = {}
    resolved: list[tuple[Drive, int, SiteGroundingRow]] = []
    for line, row in rows:
        drive = drives.get(row.drive)
        if drive is None or drive.kind != "mapping":
            why = "the site has no drive" if drive is None else "only mapping drives are grounded, not"
            raise BadInputError(f"{why} {row.drive!r}", file=filename, line=line, field="drive")
        if drive.id not in frame_ids:
            frame_ids[drive.id] = dict(
                session.execute(select(Frame.index, Frame.id).where(Frame.drive_id == drive.id)).all()
            )
        frame_id = frame_ids[drive.id].get(row.frame)
        if frame_id is None:
            raise BadInputError(
                f"drive {drive.name!r} has no frame {row.frame}", file=filename, line=line, field="frame"
            )
        resolved.append((drive, frame_id, row))
    site_drives = select(Drive.id).where(Drive.site_id == site_id).scalar_subquery()
    session.execute(delete(Grounding).where(Grounding.drive_id.in_(site_drives)))
    session.add_all(
        Grounding(
            drive_id=drive.id,
            frame_id=frame_id,
            x_m=r.x_m,
            y_m=r.y_m,
            station=r.station,
            enabled=r.enabled,
            created_by=created_by,
        )
        for drive, frame_id, r in resolved
    )
    session.flush()
    return len(resolved)
