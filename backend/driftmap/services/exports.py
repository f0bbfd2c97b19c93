"""Exports of a map version and of vehicle position history, one implementation for the CLI and the API.

Each export gathers the stored rows and hands them to a pure writer of :mod:`driftmap.formats`; the result
is the whole file as text with its media type and a file name. Formats and their layouts:
``docs/formats.md`` ("Exports").
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np
from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.errors import BadInputError, NotFoundError
from driftmap.formats.csv_exports import PoseRow, poses_text
from driftmap.formats.dxf_export import ClosureSegment, NodeMarks, map_dxf_text
from driftmap.formats.g2o import G2oGraph, g2o_text, relative_poses
from driftmap.formats.position_exports import PositionRow, positions_text, tracks_from_positions
from driftmap.formats.site_crs import SiteCrs
from driftmap.formats.trajectory_exports import (
    Track,
    geojson_text,
    kitti_text,
    kml_text,
    one_track,
    placed,
    tracks_from_poses,
    tum_text,
)
from driftmap.services.map_views import node_arrays
from driftmap.services.sites import site_crs
from driftmap.store.access_models import Vehicle, VehiclePosition
from driftmap.store.blobs import BlobStore
from driftmap.store.models import (
    Drive,
    Frame,
    MapGroundingResidual,
    MapLoopClosure,
    MapPose,
    MapVersion,
    Site,
)

MapFormat = Literal["csv", "geojson", "dxf", "kml", "tum", "kitti", "g2o"]
PositionFormat = Literal["csv", "geojson", "dxf", "kml", "tum", "kitti"]
MAP_FORMATS: tuple[str, ...] = get_args(MapFormat)
POSITION_FORMATS: tuple[str, ...] = get_args(PositionFormat)
MEDIA_TYPES: dict[str, str] = {
    "csv": "text/csv",
    "geojson": "application/geo+json",
    "dxf": "image/vnd.dxf",
    "kml": "application/vnd.google-earth.kml+xml",
    "tum": "text/plain",
    "kitti": "text/plain",
    "g2o": "text/plain",
}
EXTENSIONS: dict[str, str] = {
    "csv": "csv",
    "geojson": "geojson",
    "dxf": "dxf",
    "kml": "kml",
    "tum": "tum.txt",
    "kitti": "kitti.txt",
    "g2o": "g2o",
}
MAX_EXPORT_POSITIONS = 2_000_000  # positions one export may hold; a larger range is refused


@dataclass(frozen=True)
class ExportFile:
    """A written export: the file's ``text``, its ``media_type``, a ``filename`` to save it as, and how
    many poses or positions it holds (``records``)."""

    text: str
    media_type: str
    filename: str
    records: int


def _check_format(fmt: str, allowed: tuple[str, ...]) -> None:
    if fmt not in allowed:
        raise BadInputError(f"unknown format {fmt!r}; choose {', '.join(allowed)}", field="format")


@dataclass(frozen=True)
class _MapPoses:
    rows: list[PoseRow]
    frame_ids: list[int]


def _map_poses(session: Session, version: MapVersion, drive: str | None) -> _MapPoses:
    query = (
        select(
            MapPose.frame_id, Drive.name, Frame.index, Frame.t_s, MapPose.x_m, MapPose.y_m, MapPose.yaw_rad
        )
        .join(Frame, MapPose.frame_id == Frame.id)
        .join(Drive, Frame.drive_id == Drive.id)
        .where(MapPose.map_version_id == version.id)
        .order_by(Drive.id, Frame.index)
    )
    if drive is not None:
        query = query.where(Drive.name == drive)
    out = _MapPoses([], [])
    for fid, name, index, t, x, y, yaw in session.execute(query):
        out.frame_ids.append(int(fid))
        out.rows.append(PoseRow(drive=name, frame=index, x_m=x, y_m=y, yaw_rad=yaw, t_s=t))
    if drive is not None and not out.rows:
        raise NotFoundError(f"map version {version.version} has no drive named {drive!r}")
    return out


def _closures(session: Session, version: MapVersion) -> list[tuple[int, int, bool]]:
    """(frame_a_id, frame_b_id, accepted) of every loop closure of ``version``."""
    rows = session.execute(
        select(MapLoopClosure.frame_a_id, MapLoopClosure.frame_b_id, MapLoopClosure.accepted)
        .where(MapLoopClosure.map_version_id == version.id)
        .order_by(MapLoopClosure.id)
    )
    return [(int(a), int(b), bool(ok)) for a, b, ok in rows]


def _pose_graph(session: Session, version: MapVersion, poses: _MapPoses) -> G2oGraph:
    """The version's pose graph at its solution: a vertex per pose (ids 0.. in CSV row order), an odometry
    edge between consecutive frames of a drive, an edge per accepted closure; grounded frames fixed."""
    row_of = {fid: r for r, fid in enumerate(poses.frame_ids)}
    wTi = np.array([[p.x_m, p.y_m, p.yaw_rad] for p in poses.rows], dtype=np.float64).reshape(-1, 3)
    pairs = [(r - 1, r) for r in range(1, len(poses.rows)) if poses.rows[r].drive == poses.rows[r - 1].drive]
    pairs += [
        (row_of[a], row_of[b])
        for a, b, ok in _closures(session, version)
        if ok and a in row_of and b in row_of  # both ends among the exported drives
    ]
    grounded = session.scalars(
        select(MapGroundingResidual.frame_id).where(MapGroundingResidual.map_version_id == version.id)
    )
    edge_ij = np.array(pairs, dtype=np.int64).reshape(-1, 2)
    return G2oGraph(
        vertex_ids=np.arange(len(poses.rows), dtype=np.int64),
        wTi=wTi,
        edge_ij=edge_ij,
        iTj=relative_poses(wTi, edge_ij),
        information=np.tile(np.eye(3), (edge_ij.shape[0], 1, 1)),
        edge_lines=np.zeros(edge_ij.shape[0], dtype=np.int64),
        fixed=np.array(sorted({row_of[f] for f in grounded if f in row_of}), dtype=np.int64),
    )


def export_map(
    session: Session,
    blobs: BlobStore,
    site: Site,
    version: MapVersion,
    fmt: str,
    *,
    drive: str | None = None,
    nodes: bool = False,
    closures: bool = False,
) -> ExportFile:
    """Map version ``version`` of ``site`` as a ``fmt`` file (one of :data:`MAP_FORMATS`).

    Args:
        drive: only this mapping drive's poses (required for ``tum`` and ``kitti`` when the map has several).
        nodes: DXF only: add the ``NODES`` layer (topological nodes and edges).
        closures: DXF only: add the ``CLOSURES`` and ``CLOSURES-REJECTED`` layers.

    Raises:
        BadInputError: an unknown format (field ``format``), several drives for TUM or KITTI (``drive``).
        NotFoundError: ``drive`` is not a drive of the version.
    """
    _check_format(fmt, MAP_FORMATS)
    poses = _map_poses(session, version, drive)
    about = {"site": site.name, "map_version": version.version}
    tracks = tracks_from_poses(poses.rows)
    if fmt == "csv":
        text = poses_text(poses.rows, with_time=True)
    elif fmt == "g2o":
        comments = [
            f"driftmap map version {version.version} of site {site.name}, {len(poses.rows)} poses in site plane metres",
            "vertex ids: the rows of the CSV export (drive then frame); edges at the optimised solution with "
            "unit information; FIX: grounded frames",
        ]
        text = g2o_text(_pose_graph(session, version, poses), comments)
    elif fmt == "dxf":
        segments = None
        if closures:
            xy = {fid: (p.x_m, p.y_m) for fid, p in zip(poses.frame_ids, poses.rows, strict=True)}
            segments = [
                ClosureSegment(xy[a], xy[b], ok)
                for a, b, ok in _closures(session, version)
                if a in xy and b in xy  # both ends among the exported drives
            ]
        marks = None
        if nodes:
            arrays = node_arrays(session, blobs, version)
            marks = NodeMarks(list(zip(arrays["x_m"], arrays["y_m"], strict=True)), arrays["edges"])
        text = map_dxf_text(tracks, marks, segments)
    else:
        title = f"{site.name} map version {version.version}"
        text = _trajectory_text(fmt, tracks, title, about, "drive", site_crs(site))
    suffix = f"-{drive}" if drive is not None else ""
    return ExportFile(
        text,
        MEDIA_TYPES[fmt],
        f"{site.name}-map-v{version.version}{suffix}.{EXTENSIONS[fmt]}",
        len(poses.rows),
    )


def _trajectory_text(
    fmt: str, tracks: list[Track], title: str, about: Mapping[str, object], option: str, crs: SiteCrs
) -> str:
    """GeoJSON and KML in the site's coordinates (WGS84 with an EPSG code, else its mine grid); TUM and
    KITTI in the site plane (trajectory tools compare them with other plane trajectories)."""
    if fmt == "geojson":
        return geojson_text(placed(tracks, crs.export_xy), about, crs.export_label())
    if fmt == "kml":
        return kml_text(placed(tracks, crs.export_xy), title, about, crs.export_label())
    if fmt == "tum":
        return tum_text(one_track(tracks, "TUM", option))
    return kitti_text(one_track(tracks, "KITTI", option))


def position_rows(
    session: Session,
    site: Site,
    vehicle: str | None = None,
    since_s: float | None = None,
    until_s: float | None = None,
) -> list[PositionRow]:
    """The stored positions of ``site``'s vehicles (or the one named ``vehicle``) with
    ``since_s <= t <= until_s`` (vehicle clock, seconds), by vehicle name then ``t``.

    Raises:
        BadInputError: a non-finite bound, ``until`` before ``since``, more than
            :data:`MAX_EXPORT_POSITIONS` positions (field ``until``).
        NotFoundError: no vehicle of the site is named ``vehicle``.
    """
    for name, bound in (("since", since_s), ("until", until_s)):
        if bound is not None and not math.isfinite(bound):
            raise BadInputError(f"must be a finite number of seconds, got {bound!r}", field=name)
    if since_s is not None and until_s is not None and until_s < since_s:
        raise BadInputError(f"until ({until_s}) is before since ({since_s})", field="until")
    query = (
        select(
            Vehicle.name,
            VehiclePosition.t_s,
            VehiclePosition.x_m,
            VehiclePosition.y_m,
            VehiclePosition.yaw_rad,
            VehiclePosition.node,
            VehiclePosition.confidence,
            VehiclePosition.matched,
            VehiclePosition.lost,
            VehiclePosition.speed_mps,
        )
        .join(Vehicle, VehiclePosition.vehicle_id == Vehicle.id)
        .where(Vehicle.site_id == site.id)
        .order_by(Vehicle.name, VehiclePosition.t_s, VehiclePosition.id)
    )
    if vehicle is not None:
        found = session.scalar(select(Vehicle.id).where(Vehicle.site_id == site.id, Vehicle.name == vehicle))
        if found is None:
            raise NotFoundError(f"site {site.name!r} has no vehicle named {vehicle!r}")
        query = query.where(VehiclePosition.vehicle_id == found)
    if since_s is not None:
        query = query.where(VehiclePosition.t_s >= since_s)
    if until_s is not None:
        query = query.where(VehiclePosition.t_s <= until_s)
    rows = session.execute(query.limit(MAX_EXPORT_POSITIONS + 1)).all()
    if len(rows) > MAX_EXPORT_POSITIONS:
        raise BadInputError(
            f"more than {MAX_EXPORT_POSITIONS} positions in the range; narrow it with since and until",
            field="until",
        )
    return [
        PositionRow(name, t, x, y, yaw, node, conf, bool(matched), bool(lost), speed)
        for name, t, x, y, yaw, node, conf, matched, lost, speed in rows
    ]


def export_positions(
    session: Session,
    site: Site,
    fmt: str,
    *,
    vehicle: str | None = None,
    since_s: float | None = None,
    until_s: float | None = None,
) -> ExportFile:
    """The position history of ``site``'s vehicles (one when ``vehicle`` is given) between ``since_s`` and
    ``until_s`` as a ``fmt`` file (one of :data:`POSITION_FORMATS`); see :func:`position_rows`.

    Raises:
        BadInputError: an unknown format (``format``), a bad range (``since``/``until``), several vehicles
            for TUM or KITTI (``vehicle``).
        NotFoundError: no vehicle of the site is named ``vehicle``.
    """
    _check_format(fmt, POSITION_FORMATS)
    rows = position_rows(session, site, vehicle, since_s, until_s)
    if fmt == "csv":
        text = positions_text(rows)
    elif fmt == "dxf":  # one layer per vehicle, site plane metres like the map's
        text = map_dxf_text(tracks_from_positions(rows))
    else:
        bounds = {"since_s": since_s, "until_s": until_s}
        about = {"site": site.name} | {k: v for k, v in bounds.items() if v is not None}
        tracks = tracks_from_positions(rows)
        text = _trajectory_text(
            fmt, tracks, f"{site.name} vehicle positions", about, "vehicle", site_crs(site)
        )
    suffix = f"-{vehicle}" if vehicle is not None else ""
    return ExportFile(text, MEDIA_TYPES[fmt], f"{site.name}-positions{suffix}.{EXTENSIONS[fmt]}", len(rows))
