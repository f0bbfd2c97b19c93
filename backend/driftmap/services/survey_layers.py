"""A site's survey plan as GeoJSON layers in plane metres, simplified for the zoom it is drawn at.

Big plans hold hundreds of thousands of vertices; a map view needs only those a screen pixel can show.
Line and polygon features are simplified with shapely (Douglas-Peucker, topology preserved) to a tolerance
in metres, chosen directly or from a zoom level: at zoom 0 the plan's larger side spans 256 pixels, each
further level doubles that, and the tolerance is half a pixel. Results are cached per survey map and
tolerance (the stored layers never change: a new upload is a new survey map): in memory per process, and for
the zooms a first view asks (:data:`FIRST_VIEW_ZOOMS`) in the database, written by :func:`store_first_levels`
in the upload's own transaction, so the first view of a freshly uploaded plan is a cache hit.
"""

from __future__ import annotations

import json
import math
import threading
from collections import OrderedDict
from dataclasses import dataclass
from typing import Any

from shapely.geometry import mapping, shape
from sqlalchemy import select
from sqlalchemy.orm import Session

from driftmap.errors import BadInputError
from driftmap.store.models import SurveyLayerLevel, SurveyMap

TILE_PX = 256  # pixels the whole plan spans at zoom 0
MAX_ZOOM = 30
CACHE_SIZE = 64  # simplified plans kept in memory (per process)
# What frontend/src/map/MineMap.tsx asks first: zoom 0 (places the view), then serverZoomFor() of the
# fitted view, 1..3 for a map 256..2048 px across.
FIRST_VIEW_ZOOMS = (0, 1, 2, 3)

_cache: OrderedDict[tuple[int, str, float], dict[str, Any]] = OrderedDict()
_lock = threading.Lock()


def tolerance_for_zoom(survey: SurveyMap, zoom: float) -> float:
    """Half a screen pixel in metres when the plan is drawn at ``zoom`` (see the module docstring)."""
    if not 0 <= zoom <= MAX_ZOOM:
        raise BadInputError(f"zoom must be between 0 and {MAX_ZOOM}", field="zoom")
    side_m = max(survey.max_x_m - survey.min_x_m, survey.max_y_m - survey.min_y_m, 1e-6)
    return float(side_m / (TILE_PX * 2.0**zoom) / 2.0)


def _simplify_collection(collection: dict[str, Any], tolerance_m: float) -> tuple[dict[str, Any], int]:
    features = []
    vertices = 0
    for feature in collection.get("features", []):
        geometry = feature.get("geometry")
        if not geometry:
            features.append(feature)
            continue
        if tolerance_m > 0 and not _minimal(geometry):
            simplified = shape(geometry).simplify(tolerance_m, preserve_topology=True)
            if simplified.is_empty:
                continue
            geometry = mapping(simplified)
            feature = {**feature, "geometry": geometry}
        vertices += _vertices(geometry)
        features.append(feature)  # unchanged features are shared with the stored plan (never mutated)
    return {"type": "FeatureCollection", "features": features}, vertices


def _minimal(geometry: dict[str, Any]) -> bool:
    """Whether simplifying cannot change ``geometry``: points, and two-vertex lines (a plan's LINE entities)."""
    kind = geometry.get("type")
    return kind in ("Point", "MultiPoint") or (kind == "LineString" and len(geometry["coordinates"]) == 2)


def tolerance_key(tolerance_m: float) -> float:
    """``tolerance_m`` rounded for lookups: to 6 decimals, or 3 significant digits when that is finer.

    Plain rounding to micrometres would give the first-view zooms of a plan a few millimetres across one
    key (and make a positive tolerance look like 0, "as stored"); keeping 3 significant digits keeps the
    zooms apart (each halves the tolerance) while leaving every tolerance of 0.1 mm and more as it was.
    """
    if tolerance_m >= 1e-4 or tolerance_m == 0:
        return round(tolerance_m, 6)
    return float(f"{tolerance_m:.3g}")


def _key(survey: SurveyMap, tolerance_m: float) -> tuple[int, str, float]:
    return (survey.id, survey.dxf_sha256, tolerance_key(tolerance_m))


def _remember(key: tuple[int, str, float], whole: dict[str, Any]) -> None:
    with _lock:
        _cache[key] = whole
        _cache.move_to_end(key)
        while len(_cache) > CACHE_SIZE:
            _cache.popitem(last=False)


def _simplify_all(survey: SurveyMap, tolerance_m: float) -> dict[str, Any]:
    """``{"layers": {name: FeatureCollection}, "vertices": {name: count}}`` of every layer at ``tolerance_m``."""
    simplified: dict[str, Any] = {}
    counts: dict[str, int] = {}
    for name, collection in survey.layers.items():
        simplified[name], counts[name] = _simplify_collection(collection, tolerance_m)
    return {"layers": simplified, "vertices": counts}


@dataclass(frozen=True)
class FirstLevel:
    """A plan's layers simplified for one of :data:`FIRST_VIEW_ZOOMS`, not yet stored.

    Attributes:
        zoom: the map zoom.
        tolerance_m: the lookup key of the tolerance, metres (see :func:`tolerance_key`).
        whole: ``{"layers": {name: FeatureCollection}, "vertices": {name: count}}``.
        same_as_zoom: the coarser zoom whose layers these equal (stored once), or None.
    """

    zoom: int
    tolerance_m: float
    whole: dict[str, Any]
    same_as_zoom: int | None


def first_levels(survey: SurveyMap) -> list[FirstLevel]:
    """Simplify a plan (stored or not: no id needed) for :data:`FIRST_VIEW_ZOOMS`.

    A level whose layers equal the previous full level's (nothing more survives the finer tolerance) refers
    to it (``same_as_zoom``) rather than copying it. Zooms whose tolerances share one key (see
    :func:`tolerance_key`) get one level, the coarsest zoom's.
    """
    levels: list[FirstLevel] = []
    stored: FirstLevel | None = None  # the last level kept in full
    for zoom in FIRST_VIEW_ZOOMS:
        tolerance = tolerance_for_zoom(survey, zoom)
        key = tolerance_key(tolerance)
        if any(level.tolerance_m == key for level in levels):
            continue
        whole = _simplify_all(survey, tolerance)
        if stored is not None and whole["layers"] == stored.whole["layers"]:
            levels.append(FirstLevel(zoom, key, stored.whole, stored.zoom))  # e.g. a plan of LINE entities
        else:
            stored = FirstLevel(zoom, key, whole, None)
            levels.append(stored)
    return levels


def stored_bytes(levels: list[FirstLevel]) -> int:
    """Bytes of JSON the levels' layers take in the database (those stored in full)."""
    return sum(json_bytes(level.whole["layers"]) for level in levels if level.same_as_zoom is None)


def json_bytes(value: Any) -> int:
    """Bytes of ``value`` as JSON, written as the database's JSON columns write it (``json.dumps``)."""
    return len(json.dumps(value))  # ASCII: non-ASCII characters are escaped


def store_first_levels(
    session: Session, survey: SurveyMap, levels: list[FirstLevel] | None = None
) -> list[SurveyLayerLevel]:
    """Add a just-added plan's :func:`first_levels` (or ``levels`` computed before) to ``session``.

    Call it in the transaction that adds ``survey`` (flushed, so it has an id): the levels commit or roll
    back with the plan. They are also put in this process's memory cache (keyed by the plan's content
    hash, so an entry of a rolled-back upload can only ever answer for the same plan).

    Returns:
        The added rows, one per level, flushed.
    """
    rows: list[SurveyLayerLevel] = []
    for level in first_levels(survey) if levels is None else levels:
        _remember((survey.id, survey.dxf_sha256, level.tolerance_m), level.whole)
        rows.append(
            SurveyLayerLevel(
                survey_map_id=survey.id,
                zoom=level.zoom,
                tolerance_m=level.tolerance_m,
                vertices=level.whole["vertices"],
                layers=None if level.same_as_zoom is not None else level.whole["layers"],
                same_as_zoom=level.same_as_zoom,
            )
        )
    session.add_all(rows)
    session.flush()
    return rows


def _stored_level(session: Session, key: tuple[int, str, float]) -> dict[str, Any] | None:
    row = session.scalar(
        select(SurveyLayerLevel).where(
            SurveyLayerLevel.survey_map_id == key[0], SurveyLayerLevel.tolerance_m == key[2]
        )
    )
    if row is None:
        return None
    layers = row.layers
    if layers is None:
        layers = session.scalar(
            select(SurveyLayerLevel.layers).where(
                SurveyLayerLevel.survey_map_id == key[0], SurveyLayerLevel.zoom == row.same_as_zoom
            )
        )
    return None if layers is None else {"layers": layers, "vertices": row.vertices}


def _vertices(geometry: dict[str, Any]) -> int:
    """Vertices of a GeoJSON geometry (the common types without walking every coordinate)."""
    kind, coordinates = geometry.get("type"), geometry.get("coordinates")
    if kind in ("LineString", "MultiPoint") and isinstance(coordinates, list | tuple):
        return len(coordinates)
    if kind in ("Polygon", "MultiLineString") and isinstance(coordinates, list | tuple):
        return sum(len(part) for part in coordinates)
    return _count_vertices(coordinates)


def _count_vertices(coordinates: Any) -> int:
    if not isinstance(coordinates, list | tuple) or not coordinates:
        return 0
    if isinstance(coordinates[0], int | float):
        return 1
    return sum(_count_vertices(c) for c in coordinates)


def survey_layers(
    survey: SurveyMap,
    *,
    tolerance_m: float = 0.0,
    layers: list[str] | None = None,
    session: Session | None = None,
) -> dict[str, Any]:
    """The plan's layers as GeoJSON FeatureCollections (plane metres), simplified to ``tolerance_m``.

    Looked up in the memory cache, then (with ``session``) among the levels stored at upload, and only then
    computed from the stored plan.

    Args:
        survey: the stored survey map.
        tolerance_m: largest distance a simplified line may move from the original, metres (0: as stored).
        layers: only these layer names (all when None).
        session: the survey's session, to read the levels stored at upload.

    Returns:
        ``{"survey_map_id", "tolerance_m", "extents": [min_x, min_y, max_x, max_y], "vertices",
        "layers": {name: FeatureCollection}}``.

    Raises:
        BadInputError: a negative or non-finite tolerance, or an unknown layer name.
    """
    if not (math.isfinite(tolerance_m) and tolerance_m >= 0):
        raise BadInputError("tolerance_m must be a finite number >= 0", field="tolerance_m")
    if layers is not None:
        unknown = sorted(set(layers) - set(survey.layers))
        if unknown:
            raise BadInputError(
                f"unknown layer(s) {', '.join(unknown)}; the plan has {', '.join(sorted(survey.layers))}",
                field="layers",
            )
    key = _key(survey, tolerance_m)
    with _lock:
        whole = _cache.get(key)
        if whole is not None:
            _cache.move_to_end(key)
    if whole is None:
        whole = _stored_level(session, key) if session is not None else None
        if whole is None:
            whole = _simplify_all(survey, tolerance_m)
        _remember(key, whole)
    names = layers if layers is not None else list(whole["layers"])
    return {
        "survey_map_id": survey.id,
        "tolerance_m": tolerance_m,
        "extents": [survey.min_x_m, survey.min_y_m, survey.max_x_m, survey.max_y_m],
        "vertices": sum(whole["vertices"][n] for n in names),
        "layers": {n: whole["layers"][n] for n in names},
    }
