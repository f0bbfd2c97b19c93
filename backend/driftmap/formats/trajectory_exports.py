"""Trajectories written for trajectory tools and GIS: TUM, KITTI, GeoJSON and KML (``docs/formats.md``).

A :class:`Track` is one named trajectory (a mapping drive of a map version, or a vehicle's position
history) in the site plane: x east, y north, metres, the floor point under the camera; heading ``yaw``
in radians counter-clockwise from +x. GeoJSON and KML say in the file what their coordinates are: these
plane coordinates, or a site's mine grid or WGS84 longitude and latitude (:func:`placed`,
:mod:`driftmap.formats.site_crs`). Every ``*_text`` function is pure and
returns the whole file as text; numbers are written with :func:`repr` (the shortest text that reads back
as the identical float).
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from typing import Any
from xml.sax.saxutils import escape

import numpy as np

from driftmap.core.types import F64
from driftmap.errors import BadInputError
from driftmap.formats.csv_exports import PoseRow
from driftmap.formats.tables import format_float

PLANE_COORDINATES = "site plane metres"
"""What the coordinates of a GeoJSON or KML export are: mine-grid x east, y north, metres (no CRS)."""
COORDINATES_MEMBER = "driftmap:coordinates"
"""The GeoJSON foreign member (RFC 7946 section 6.1) and KML ``ExtendedData`` name that says so."""
KML_NAMESPACE = "http://www.opengis.net/kml/2.2"


@dataclass(frozen=True)
class TrackPose:
    """One pose of a track.

    ``t_s`` is seconds (a drive's time since its start, or a vehicle's clock); ``x_m, y_m`` the floor
    point under the camera in the site plane, metres; ``yaw_rad`` the heading, radians counter-clockwise
    from +x, None when unknown; ``frame`` the drive's frame number (None for vehicle positions).
    """

    t_s: float
    x_m: float
    y_m: float
    yaw_rad: float | None
    frame: int | None = None


@dataclass(frozen=True)
class Track:
    """A named trajectory, poses in time order; ``kind`` says what ``name`` names: ``drive`` or ``vehicle``."""

    name: str
    kind: str
    poses: tuple[TrackPose, ...]


def _number(value: float, field: str) -> str:
    return format_float(value, field=field)


def yaw_quaternion(yaw_rad: float | None) -> tuple[float, float, float, float]:
    """The unit quaternion ``(qx, qy, qz, qw)`` of a rotation by ``yaw_rad`` about +z (identity when None)."""
    if yaw_rad is None:
        return (0.0, 0.0, 0.0, 1.0)
    return (0.0, 0.0, math.sin(yaw_rad / 2.0), math.cos(yaw_rad / 2.0))


def one_track(tracks: Sequence[Track], fmt: str, option: str) -> Track:
    """The single track of a format that holds one trajectory per file (TUM, KITTI).

    Raises:
        BadInputError: none or several tracks, naming ``option`` (the parameter that picks one).
    """
    if len(tracks) == 1:
        return tracks[0]
    if not tracks:
        raise BadInputError(f"nothing to export as {fmt}: no poses", field=option)
    names = ", ".join(repr(t.name) for t in tracks[:5]) + (", ..." if len(tracks) > 5 else "")
    raise BadInputError(
        f"{fmt} holds one trajectory per file and there are {len(tracks)} ({names}): pick one {option}",
        field=option,
    )


def tum_text(track: Track) -> str:
    """A TUM RGB-D trajectory: one line ``timestamp tx ty tz qx qy qz qw`` per pose, space-separated.

    The pose is world-from-vehicle in the site plane lifted to 3-D: translation ``(x, y, 0)`` metres,
    rotation ``yaw`` about +z as a unit quaternion (the identity when the heading is unknown);
    ``timestamp`` is ``t_s``, seconds. Two ``#`` comment lines name the track and the frame.
    """
    lines = [
        f"# driftmap {track.kind} {track.name}: world-from-vehicle, {PLANE_COORDINATES}, z up, t in seconds",
        "# timestamp tx ty tz qx qy qz qw",
    ]
    for p in track.poses:
        q = yaw_quaternion(p.yaw_rad)
        values = [_number(p.t_s, "t"), _number(p.x_m, "x"), _number(p.y_m, "y"), "0.0"]
        lines.append(" ".join(values + [repr(float(c)) for c in q]))
    return "\n".join(lines) + "\n"


def kitti_text(track: Track) -> str:
    """A KITTI odometry pose file: one line of 12 numbers per pose, the 3x4 matrix [R | t] row-major.

    The pose is world-from-vehicle in the *site plane's* frame (x east, y north, z up; not KITTI's camera
    frame x right, y down, z forward): R the rotation by ``yaw`` about +z (identity when unknown),
    t = (x, y, 0) metres. KITTI carries no timestamps and no comments.
    """
    lines = []
    for p in track.poses:
        yaw = p.yaw_rad or 0.0
        c, s = math.cos(yaw), math.sin(yaw)
        x, y = _number(p.x_m, "x"), _number(p.y_m, "y")
        row = [repr(c), repr(-s), "0.0", x, repr(s), repr(c), "0.0", y, "0.0", "0.0", "1.0", "0.0"]
        lines.append(" ".join(row))
    return "".join(line + "\n" for line in lines)


def _feature(track: Track, extra: dict[str, Any]) -> dict[str, Any]:
    coordinates = [[float(_number(p.x_m, "x")), float(_number(p.y_m, "y"))] for p in track.poses]
    geometry: dict[str, Any] = (
        {"type": "Point", "coordinates": coordinates[0]}
        if len(coordinates) == 1
        else {"type": "LineString", "coordinates": coordinates}
    )
    properties: dict[str, Any] = {
        track.kind: track.name,
        "t_s": [float(_number(p.t_s, "t")) for p in track.poses],
        "yaw_rad": [p.yaw_rad for p in track.poses],
    }
    if all(p.frame is not None for p in track.poses):
        properties["frame"] = [p.frame for p in track.poses]
    return {"type": "Feature", "geometry": geometry, "properties": properties | extra}


def geojson_text(
    tracks: Sequence[Track], about: Mapping[str, Any] | None = None, coordinates: str = PLANE_COORDINATES
) -> str:
    """A GeoJSON FeatureCollection (RFC 7946) with one Feature per track.

    Each track is a LineString of ``[x, y]`` positions (a Point when it has one pose), whose ``properties``
    name it (key ``drive`` or ``vehicle``) and hold per-pose arrays ``t_s`` (seconds), ``yaw_rad`` (radians
    in the site plane, null when unknown) and, for drives, ``frame``. The collection carries the foreign
    member ``"driftmap:coordinates"`` saying what x, y are (``coordinates``: site plane metres unless the
    tracks were :func:`placed`) and ``about``'s keys prefixed ``driftmap:``. Tracks without poses are left out.
    """
    collection: dict[str, Any] = {"type": "FeatureCollection", COORDINATES_MEMBER: coordinates}
    for key, value in (about or {}).items():
        collection[f"driftmap:{key}"] = value
    collection["features"] = [_feature(t, {}) for t in tracks if t.poses]
    return json.dumps(collection, indent=1, allow_nan=False) + "\n"


def _data(name: str, value: object) -> str:
    return f'<Data name="{escape(name, {chr(34): "&quot;"})}"><value>{escape(str(value))}</value></Data>'


def kml_text(
    tracks: Sequence[Track],
    title: str,
    about: Mapping[str, Any] | None = None,
    coordinates: str = PLANE_COORDINATES,
) -> str:
    """A KML 2.2 document with one Placemark per track: a LineString (a Point for one pose).

    Coordinates are ``x,y,0``: longitude and latitude when the tracks were :func:`placed` on the Earth, else
    site plane (or mine grid) metres; the document's ``ExtendedData`` says which (``driftmap:coordinates``,
    ``coordinates``) with ``about``'s keys; each Placemark is named by its drive or vehicle and carries
    ``kind``, ``poses``, ``t_start_s`` and ``t_end_s``. Tracks without poses are left out.
    """
    meta = {COORDINATES_MEMBER: coordinates} | {f"driftmap:{k}": v for k, v in (about or {}).items()}
    out = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        f'<kml xmlns="{KML_NAMESPACE}">',
        "<Document>",
        f"<name>{escape(title)}</name>",
        "<ExtendedData>" + "".join(_data(k, v) for k, v in meta.items()) + "</ExtendedData>",
    ]
    for track in tracks:
        if not track.poses:
            continue
        points = " ".join(f"{_number(p.x_m, 'x')},{_number(p.y_m, 'y')},0" for p in track.poses)
        shape = "Point" if len(track.poses) == 1 else "LineString"
        facts = {
            "kind": track.kind,
            "poses": len(track.poses),
            "t_start_s": _number(track.poses[0].t_s, "t"),
            "t_end_s": _number(track.poses[-1].t_s, "t"),
        }
        out += [
            "<Placemark>",
            f"<name>{escape(track.name)}</name>",
            "<ExtendedData>" + "".join(_data(k, v) for k, v in facts.items()) + "</ExtendedData>",
            f"<{shape}><coordinates>{points}</coordinates></{shape}>",
            "</Placemark>",
        ]
    out += ["</Document>", "</kml>"]
    return "\n".join(out) + "\n"


def placed(tracks: Sequence[Track], to_xy: Callable[[F64], F64]) -> list[Track]:
    """The ``tracks`` with every pose's x, y mapped by ``to_xy`` ((N, 2) plane metres -> (N, 2)), e.g. a
    site's :meth:`driftmap.formats.site_crs.SiteCrs.export_xy`; times, headings and frames unchanged."""
    out = []
    for track in tracks:
        if not track.poses:
            out.append(track)
            continue
        xy = to_xy(np.array([[p.x_m, p.y_m] for p in track.poses], dtype=np.float64))
        poses = tuple(
            replace(p, x_m=float(x), y_m=float(y)) for p, (x, y) in zip(track.poses, xy, strict=True)
        )
        out.append(replace(track, poses=poses))
    return out


def tracks_from_poses(rows: Sequence[PoseRow]) -> list[Track]:
    """Map poses (drive then frame order, each with its time ``t_s``) as one ``drive`` track per drive."""
    tracks: dict[str, list[TrackPose]] = {}
    for r in rows:
        if r.t_s is None:
            raise ValueError(f"drive {r.drive!r} frame {r.frame} has no time t")
        tracks.setdefault(r.drive, []).append(TrackPose(r.t_s, r.x_m, r.y_m, r.yaw_rad, r.frame))
    return [Track(name, "drive", tuple(poses)) for name, poses in tracks.items()]
