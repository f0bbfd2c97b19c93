"""Groundings: a surveyor's statement that a frame of a mapping drive was taken at a surveyed point.

Create, move and delete single groundings; list a site's groundings with their residuals in the latest map
version; import and export a drive's groundings in the ``groundings.csv`` format of formats.md. An import
replaces the drive's groundings as a whole, after the whole file has been checked (errors name the line).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sqlalchemy import delete, select
from sqlalchemy.orm import Session

from driftmap.errors import BadInputError, ConflictError, NotFoundError
from driftmap.formats.csv_exports import groundings_text, parse_groundings_rows
from driftmap.formats.records import GroundingRow
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
    created_by: str
    residual_m: float | None
    """Distance from the optimised pose to the surveyed point in the latest map version, metres."""
    map_version: int | None
    """The map version of ``residual_m``; None when the grounding is newer than the latest build."""


def _check_point(x_m: float, y_m: float) -> None:
    for name, value in (("x", x_m), ("y", y_m)):
        if not math.isfinite(value):
            raise BadInputError(f"{name} must be a finite number of metres", field=name)


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
    session: Session, drive: Drive, frame_index: int, x_m: float, y_m: float, created_by: str
) -> Grounding:
    """Ground frame ``frame_index`` of ``drive`` at survey point (x_m, y_m); one grounding per frame."""
    _check_point(x_m, y_m)
    if drive.kind != "mapping":
        raise BadInputError(f"drive {drive.name!r} is a {drive.kind} drive; only mapping drives are grounded")
    frame = _frame_of(session, drive, frame_index)
    if session.scalar(select(Grounding.id).where(Grounding.frame_id == frame.id)) is not None:
        raise ConflictError(f"frame {frame_index} of drive {drive.name!r} is already grounded")
    grounding = Grounding(drive_id=drive.id, frame_id=frame.id, x_m=x_m, y_m=y_m, created_by=created_by)
    session.add(grounding)
    session.flush()
    return grounding


def update_grounding(
    session: Session, grounding: Grounding, *, x_m: float | None = None, y_m: float | None = None
) -> Grounding:
    """Move a grounding's surveyed point."""
    new_x = grounding.x_m if x_m is None else x_m
    new_y = grounding.y_m if y_m is None else y_m
    _check_point(new_x, new_y)
    grounding.x_m, grounding.y_m = new_x, new_y
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
        Grounding(drive_id=drive.id, frame_id=frame_ids[r.frame], x_m=r.x_m, y_m=r.y_m, created_by=created_by)
        for _line, r in rows
    )
    session.flush()
    return len(rows)
