"""The site survey plan: a DXF in mine-grid plane metres (``docs/formats.md``), parsed into layers.

Every drawable entity becomes a GeoJSON-like feature in plane metres (x east, y north, z dropped):

* LINE, LWPOLYLINE (bulges become arcs), POLYLINE (2D and 3D), ARC, CIRCLE, ELLIPSE and SPLINE become
  ``LineString`` features; curves are flattened so that no chord strays more than
  :data:`SAGITTA_M` from the curve. Closed shapes stay ``LineString`` (never ``Polygon``: a closed wall
  outline is a line, not necessarily a valid area) whose last point repeats the first, with
  ``properties.closed = true``.
* TEXT, MTEXT and the ATTRIBs of block references become ``Point`` features at their insertion point
  with ``properties.text``; POINT entities become ``Point`` features without text.
* INSERT (and MINSERT) block references are exploded recursively with their transforms; entities on
  layer ``0`` inside a block take the layer of the reference, as in CAD programs.
* Everything else (HATCH, DIMENSION, 3D solids, images, ...) is counted in ``skipped`` and left out.

``$INSUNITS`` scales the drawing to metres (0 = unitless and 6 = metres are taken as metres).
"""

from __future__ import annotations

import io
import math
import os
import tempfile
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

from ezdxf import path as ezpath
from ezdxf.document import Drawing
from ezdxf.entities.dxfgfx import DXFGraphic
from ezdxf.entities.insert import Insert
from ezdxf.filemanagement import read as read_dxf_stream
from ezdxf.filemanagement import readfile as read_dxf_file
from ezdxf.lldxf.const import DXFError

from driftmap.errors import BadInputError

SAGITTA_M = 0.05  # largest distance between a flattened curve and its chords, metres
_MAX_BLOCK_DEPTH = 16  # nested block references deeper than this are taken as a cycle
_BINARY_DXF_MAGIC = b"AutoCAD Binary DXF"
_CURVES = frozenset({"LINE", "LWPOLYLINE", "POLYLINE", "ARC", "CIRCLE", "ELLIPSE", "SPLINE"})
_TEXTS = frozenset({"TEXT", "MTEXT", "ATTRIB"})
# metres per drawing unit by $INSUNITS code (AutoCAD's list; astronomical units left out)
METRES_PER_UNIT: dict[int, float] = {
    0: 1.0, 1: 0.0254, 2: 0.3048, 3: 1609.344, 4: 1e-3, 5: 1e-2, 6: 1.0, 7: 1e3, 8: 2.54e-8, 9: 2.54e-5,
    10: 0.9144, 11: 1e-10, 12: 1e-9, 13: 1e-6, 14: 0.1, 15: 10.0, 16: 100.0, 17: 1e9,
    21: 1200 / 3937, 22: 0.0254 * 1.000002, 23: 0.9144 * 1.000002, 24: 1609.344 * 1.000002,
}  # fmt: skip

Extents = tuple[float, float, float, float]  # (min_x, min_y, max_x, max_y), metres


@dataclass(frozen=True)
class SurveyLayer:
    """The features of one DXF layer.

    Attributes:
        name: the layer name as written in the DXF.
        features: a GeoJSON FeatureCollection dict, coordinates in plane metres.
        extents: (min_x, min_y, max_x, max_y) of the layer's coordinates, metres.
        counts: number of features per DXF entity type (``LWPOLYLINE``, ``TEXT``, ...).
    """

    name: str
    features: dict[str, Any]
    extents: Extents
    counts: dict[str, int]


@dataclass(frozen=True)
class SurveyMap:
    """A parsed survey plan.

    Attributes:
        source: the file name the plan came from (used in messages).
        insunits: the ``$INSUNITS`` code of the DXF (0 when absent).
        metres_per_unit: the scale applied to the drawing's coordinates.
        layers: layer name -> layer, in name order; only layers holding features.
        extents: (min_x, min_y, max_x, max_y) over all layers, metres.
        skipped: number of left-out entities per DXF entity type.
    """

    source: str
    insunits: int
    metres_per_unit: float
    layers: dict[str, SurveyLayer]
    extents: Extents
    skipped: dict[str, int] = field(default_factory=dict)


def read_survey_dxf(data: bytes, source: str) -> SurveyMap:
    """Parse a DXF survey plan into per-layer features in plane metres.

    Args:
        data: the DXF file's bytes (ASCII DXF in UTF-8 or cp1252, or binary DXF).
        source: the file name, used in error messages.

    Raises:
        BadInputError: bytes that are not a readable DXF (with ezdxf's line when it gives one), a
            truncated file, an unknown ``$INSUNITS``, or a plan without drawable entities.
    """
    doc = _load(data, source)
    insunits = int(doc.header.get("$INSUNITS", 0) or 0)
    if insunits not in METRES_PER_UNIT:
        raise BadInputError(f"unsupported $INSUNITS code {insunits}", file=source, field="$INSUNITS")
    scale = METRES_PER_UNIT[insunits]
    features: dict[str, list[dict[str, Any]]] = {}
    counts: dict[str, Counter[str]] = {}
    skipped: Counter[str] = Counter()
    for layer, dxftype, feature in _features(doc, scale, skipped):
        features.setdefault(layer, []).append(feature)
        counts.setdefault(layer, Counter())[dxftype] += 1
    if not features:
        found = ", ".join(f"{n} {t}" for t, n in sorted(skipped.items())) or "nothing"
        raise BadInputError(
            f"the DXF has no drawable entities in its model space (found {found})", file=source
        )
    layers = {
        name: SurveyLayer(
            name=name,
            features={"type": "FeatureCollection", "features": features[name]},
            extents=_extents(features[name]),
            counts=dict(sorted(counts[name].items())),
        )
        for name in sorted(features)
    }
    extents = _union([layer.extents for layer in layers.values()])
    return SurveyMap(source, insunits, scale, layers, extents, dict(sorted(skipped.items())))


def survey_map_to_json(survey: SurveyMap) -> dict[str, Any]:
    """The parsed layers of ``survey`` as plain JSON, for storage.

    Returns:
        Layer name -> GeoJSON FeatureCollection dict (coordinates in plane metres) with two extra
        members: ``extents`` ``[min_x, min_y, max_x, max_y]`` (metres) and ``counts`` (features per DXF
        entity type). The plan's ``source``, ``insunits`` and ``skipped`` are not included; store them
        beside it if needed and hand them back to :func:`survey_map_from_json`.
    """
    return {
        name: {**layer.features, "extents": list(layer.extents), "counts": dict(layer.counts)}
        for name, layer in survey.layers.items()
    }


def survey_map_from_json(
    layers: dict[str, Any],
    *,
    source: str = "stored survey map",
    insunits: int = 6,
    metres_per_unit: float = 1.0,
    skipped: dict[str, int] | None = None,
) -> SurveyMap:
    """Rebuild a :class:`SurveyMap` from :func:`survey_map_to_json` output.

    Args:
        layers: the stored layers.
        source: the plan's file name.
        insunits: the ``$INSUNITS`` code the plan had (its coordinates are metres whatever it was).
        metres_per_unit: the scale that was applied.
        skipped: the counts of left-out entities.

    Raises:
        BadInputError: ``layers`` is not what :func:`survey_map_to_json` writes.
    """
    try:
        if not isinstance(layers, dict) or not layers:
            raise TypeError("expected a non-empty dict of layers")
        parsed: dict[str, SurveyLayer] = {}
        for name, layer in layers.items():
            if layer["type"] != "FeatureCollection" or not isinstance(layer["features"], list):
                raise TypeError(f"layer {name!r} is not a FeatureCollection")
            parsed[str(name)] = SurveyLayer(
                name=str(name),
                features={"type": "FeatureCollection", "features": list(layer["features"])},
                extents=_as_extents(layer["extents"]),
                counts={str(k): int(v) for k, v in layer["counts"].items()},
            )
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise BadInputError(f"stored survey map is damaged: {exc}", file=source, field="layers") from None
    boxes = [layer.extents for layer in parsed.values()]
    return SurveyMap(source, insunits, metres_per_unit, parsed, _union(boxes), dict(skipped or {}))


# ----------------------------------------------------------------------------------------------- loading


def _load(data: bytes, source: str) -> Drawing:
    if data.startswith(_BINARY_DXF_MAGIC):
        return _load_binary(data, source)
    text = _decode(data, source)
    last_tags = [line.strip() for line in text.rstrip().rsplit("\n", 2)[-2:]]
    if last_tags != ["0", "EOF"]:
        raise BadInputError("not a complete DXF file (no '0 / EOF' at the end; truncated?)", file=source)
    try:
        return read_dxf_stream(io.StringIO(text))
    except DXFError as exc:
        raise BadInputError(f"not a readable DXF: {exc}", file=source) from None
    except Exception as exc:  # ezdxf raises assorted errors on malformed tags
        raise BadInputError(f"not a readable DXF: {type(exc).__name__}: {exc}", file=source) from None


def _load_binary(data: bytes, source: str) -> Drawing:
    fd, tmp = tempfile.mkstemp(suffix=".dxf")
    try:
        with os.fdopen(fd, "wb") as handle:
            handle.write(data)
        return read_dxf_file(tmp)
    except Exception as exc:  # ezdxf raises assorted errors on malformed binary data
        raise BadInputError(f"not a readable binary DXF: {type(exc).__name__}: {exc}", file=source) from None
    finally:
        os.unlink(tmp)


def _decode(data: bytes, source: str) -> str:
    if b"\x00" in data[:4096]:
        raise BadInputError("not a DXF file (binary data)", file=source)
    for encoding in ("utf-8-sig", "cp1252"):
        try:
            return data.decode(encoding)
        except UnicodeDecodeError:
            continue
    raise BadInputError("not a DXF file (text is neither UTF-8 nor cp1252)", file=source)


# ----------------------------------------------------------------------------------------------- entities


def _features(doc: Drawing, scale: float, skipped: Counter[str]) -> Iterator[tuple[str, str, dict[str, Any]]]:
    """(layer, DXF type, feature) for each drawable entity of model space, blocks exploded."""
    for entity in doc.modelspace():
        yield from _entity_features(entity, entity.dxf.layer, scale, skipped, 0)


def _entity_features(
    entity: DXFGraphic, layer: str, scale: float, skipped: Counter[str], depth: int
) -> Iterator[tuple[str, str, dict[str, Any]]]:
    dxftype = entity.dxftype()
    if dxftype == "INSERT":
        yield from _insert_features(entity, layer, scale, skipped, depth)  # type: ignore[arg-type]
        return
    try:
        if dxftype in _CURVES and not _is_mesh(entity):
            feature = _line_feature(entity, scale)
        elif dxftype in _TEXTS:
            feature = _text_feature(entity, scale)
        elif dxftype == "POINT":
            feature = _point_feature(entity.dxf.location, scale, {"entity": "POINT"})
        else:
            feature = None
    except Exception:  # a damaged entity is left out, not the whole plan
        feature = None
    if feature is None:
        skipped[dxftype] += 1
    else:
        yield layer, dxftype, feature


def _insert_features(
    insert: Insert, layer: str, scale: float, skipped: Counter[str], depth: int
) -> Iterator[tuple[str, str, dict[str, Any]]]:
    if depth >= _MAX_BLOCK_DEPTH:
        skipped["INSERT"] += 1
        return
    inserts = list(insert.multi_insert()) if insert.mcount > 1 else [insert]
    for single in inserts:
        try:
            children = list(single.virtual_entities())
        except Exception:  # a reference to a missing or broken block
            skipped["INSERT"] += 1
            continue
        for child in children:
            child_layer = layer if child.dxf.layer == "0" else child.dxf.layer
            yield from _entity_features(child, child_layer, scale, skipped, depth + 1)
        for attrib in single.attribs:
            yield from _entity_features(attrib, attrib.dxf.layer, scale, skipped, depth + 1)


def _is_mesh(entity: DXFGraphic) -> bool:
    return entity.dxftype() == "POLYLINE" and bool(entity.is_poly_face_mesh or entity.is_polygon_mesh)  # type: ignore[attr-defined]


def _line_feature(entity: DXFGraphic, scale: float) -> dict[str, Any] | None:
    dxftype, sagitta = entity.dxftype(), SAGITTA_M / scale
    if dxftype in ("ARC", "CIRCLE"):  # exact points on the curve, not on a Bezier approximation
        vertices = entity.flattening(sagitta)  # type: ignore[attr-defined]
    elif dxftype in ("ELLIPSE", "SPLINE"):
        vertices = entity.flattening(sagitta, segments=16)  # type: ignore[attr-defined]
    else:  # LINE and polylines; bulges become cubic Beziers within ~1e-4 of the arc radius
        vertices = ezpath.make_path(entity).flattening(sagitta, segments=16)
    points = [(v.x * scale, v.y * scale) for v in vertices]
    closed = dxftype == "CIRCLE" or _closed_flag(entity)
    if dxftype == "ELLIPSE":
        closed = math.isclose(abs(entity.dxf.end_param - entity.dxf.start_param), math.tau, abs_tol=1e-9)
    if closed and points and points[0] != points[-1]:
        points.append(points[0])
    points = [p for i, p in enumerate(points) if i == 0 or p != points[i - 1]]
    if len(points) < 2 or not all(math.isfinite(c) for p in points for c in p):
        return None
    return {
        "type": "Feature",
        "geometry": {"type": "LineString", "coordinates": [list(p) for p in points]},
        "properties": {"entity": dxftype, "closed": bool(closed)},
    }


def _closed_flag(entity: DXFGraphic) -> bool:
    dxftype = entity.dxftype()
    if dxftype == "LWPOLYLINE":
        return bool(entity.closed)  # type: ignore[attr-defined]
    if dxftype == "POLYLINE":
        return bool(entity.is_closed)  # type: ignore[attr-defined]
    if dxftype == "SPLINE":
        return bool(entity.closed)  # type: ignore[attr-defined]
    return False


def _text_feature(entity: DXFGraphic, scale: float) -> dict[str, Any] | None:
    # MTEXT's insertion point is in world coordinates, TEXT's and ATTRIB's in the entity's OCS
    location = entity.dxf.insert if entity.dxftype() == "MTEXT" else entity.ocs().to_wcs(entity.dxf.insert)
    text = entity.plain_text()  # type: ignore[attr-defined]
    if not isinstance(text, str):
        return None
    properties = {"entity": entity.dxftype(), "text": text}
    if entity.dxftype() == "ATTRIB":
        properties["tag"] = entity.dxf.tag
    return _point_feature(location, scale, properties)


def _point_feature(location: Any, scale: float, properties: dict[str, Any]) -> dict[str, Any] | None:
    x, y = float(location[0]) * scale, float(location[1]) * scale
    if not (math.isfinite(x) and math.isfinite(y)):
        return None
    return {"type": "Feature", "geometry": {"type": "Point", "coordinates": [x, y]}, "properties": properties}


def _extents(features: list[dict[str, Any]]) -> Extents:
    xs: list[float] = []
    ys: list[float] = []
    for feature in features:
        geometry = feature["geometry"]
        coords = [geometry["coordinates"]] if geometry["type"] == "Point" else geometry["coordinates"]
        xs.extend(c[0] for c in coords)
        ys.extend(c[1] for c in coords)
    return (min(xs), min(ys), max(xs), max(ys))


def _union(boxes: list[Extents]) -> Extents:
    return (
        min(b[0] for b in boxes),
        min(b[1] for b in boxes),
        max(b[2] for b in boxes),
        max(b[3] for b in boxes),
    )


def _as_extents(values: Any) -> Extents:
    a, b, c, d = (float(v) for v in values)
    return (a, b, c, d)
