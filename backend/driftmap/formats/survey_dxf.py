"""The site survey plan: a DXF in mine-grid plane metres (``docs/formats.md``), parsed into layers.

Every drawable entity becomes a GeoJSON-like feature in plane metres (x east, y north, z dropped):

* LINE, LWPOLYLINE (bulges become arcs), POLYLINE (2D and 3D), ARC, CIRCLE, ELLIPSE and SPLINE become
  ``LineString`` features; curves are flattened so that no chord strays more than
  :data:`SAGITTA_M` from the curve. Closed shapes stay ``LineString`` (never ``Polygon``: a closed wall
  outline is a line, not necessarily a valid area) whose last point repeats the first, with
  ``properties.closed = true``.
* HATCH (and MPOLYGON) boundary paths, polyline and edge paths alike (lines, arcs, ellipses, splines),
  become one closed ``LineString`` each; the fill itself is not drawn.
* TEXT, MTEXT and the ATTRIBs of block references become ``Point`` features at their insertion point
  with ``properties.text`` (and ``properties.height_m``, the lettering's height, when the entity has one);
  POINT entities become ``Point`` features without text.
* INSERT (and MINSERT) block references are exploded recursively with their transforms; entities on
  layer ``0`` inside a block take the layer of the reference, as in CAD programs.
* Everything else (DIMENSION, 3D solids, meshes, images, ...) is counted in ``skipped`` and left out.

``$INSUNITS`` scales the drawing to metres (0 = unitless and 6 = metres are taken as metres). ASCII DXF
(UTF-8 or cp1252, any line ending) and binary DXF are read; an ASCII file the strict reader refuses is read
again with ezdxf's recovery mode. The cost of a plan is bounded by :class:`DxfLimits` (file size, entities,
extent, points per curve and in all; see :mod:`driftmap.formats.survey_entities`).
"""

from __future__ import annotations

import io
import logging
import os
import tempfile
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

from ezdxf import recover
from ezdxf.document import Drawing
from ezdxf.filemanagement import read as read_dxf_stream
from ezdxf.filemanagement import readfile as read_dxf_file
from ezdxf.lldxf.const import DXFError

from driftmap.errors import BadInputError, PayloadTooLargeError
from driftmap.formats.survey_entities import DEFAULT_LIMITS, SAGITTA_M, DxfLimits, EntityReader

__all__ = [
    "DEFAULT_LIMITS",
    "METRES_PER_UNIT",
    "SAGITTA_M",
    "DxfLimits",
    "SurveyLayer",
    "SurveyMap",
    "read_survey_dxf",
    "survey_map_from_json",
    "survey_map_to_json",
]

log = logging.getLogger(__name__)

_BINARY_DXF_MAGIC = b"AutoCAD Binary DXF"
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


def read_survey_dxf(data: bytes, source: str, limits: DxfLimits = DEFAULT_LIMITS) -> SurveyMap:
    """Parse a DXF survey plan into per-layer features in plane metres.

    Args:
        data: the DXF file's bytes (ASCII DXF in UTF-8 or cp1252, or binary DXF).
        source: the file name, used in error messages.
        limits: bounds on the file size, entities, extent (metres) and flattened points.

    Raises:
        PayloadTooLargeError: a file, entity count or point count over its limit (the message names the
            entity and the setting).
        BadInputError: bytes that are not a readable DXF (with ezdxf's line when it gives one), a
            truncated file, an unknown ``$INSUNITS``, a drawing wider than ``limits.max_extent_m``, or a
            plan without drawable entities.
    """
    if len(data) > limits.max_file_bytes:
        raise PayloadTooLargeError(
            f"a DXF of {len(data)} bytes is over the {limits.max_file_bytes} byte limit "
            "(setting survey_max_file_bytes)",
            file=source,
        )
    if not data.startswith(_BINARY_DXF_MAGIC):
        coordinates = _coordinate_tags(data)
        if coordinates > limits.max_points:
            raise PayloadTooLargeError(
                f"the DXF holds {coordinates} coordinates (group code 10), more than the limit of "
                f"{limits.max_points} points (setting survey_max_points)",
                file=source,
            )
    doc = _load(data, source)
    insunits = _insunits(doc, source)
    scale = METRES_PER_UNIT[insunits]
    features: dict[str, list[dict[str, Any]]] = {}
    counts: dict[str, Counter[str]] = {}
    reader = EntityReader(scale, limits, source)
    for layer, dxftype, feature in reader.features(doc):
        features.setdefault(layer, []).append(feature)
        counts.setdefault(layer, Counter())[dxftype] += 1
    skipped = reader.skipped
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
    """The document in ``data``: binary DXF, else ASCII read strictly, else read in recovery mode."""
    if data.startswith(_BINARY_DXF_MAGIC):
        return _load_binary(data, source)
    text = _decode(data, source)
    if [line.strip() for line in text[-64:].rstrip().splitlines()[-2:]] != ["0", "EOF"]:
        raise BadInputError("not a complete DXF file (no '0 / EOF' at the end; truncated?)", file=source)
    try:
        return read_dxf_stream(io.StringIO(text, newline=None))  # CR LF and CR line ends read as LF
    except DXFError as exc:
        strict_error = str(exc)
    except Exception as exc:  # ezdxf raises assorted errors on malformed tags
        strict_error = f"{type(exc).__name__}: {exc}"
    del text
    try:
        doc, auditor = recover.read(io.BytesIO(data))
    except Exception:  # the strict reader's message names the line at fault
        raise BadInputError(f"not a readable DXF: {strict_error}", file=source) from None
    log.warning(
        "%s: read in recovery mode (%s); %d problems fixed, %d left",
        source,
        strict_error,
        len(auditor.fixes),
        len(auditor.errors),
    )
    return doc


def _coordinate_tags(data: bytes) -> int:
    """How many group code 10 tags (the x of a point or vertex) ASCII DXF ``data`` holds, counted unparsed.

    A value line reading ``10`` counts too (rare); so the count is at least the points written, block
    contents once, which is what lets a plan far over the point limit be refused before ezdxf parses it.
    """
    head = data[:4096]
    end = b"\r\n" if b"\r\n" in head else b"\n" if b"\n" in head else b"\r"
    return sum(data.count(end + code + end) for code in (b"10", b" 10", b"  10"))


def _insunits(doc: Drawing, source: str) -> int:
    """The ``$INSUNITS`` code of ``doc`` (0 when absent), refused when it has no scale to metres."""
    value = doc.header.get("$INSUNITS", 0)
    try:
        insunits = int(value or 0)
    except (TypeError, ValueError):
        raise BadInputError(f"$INSUNITS is not a code: {value!r}", file=source, field="$INSUNITS") from None
    if insunits not in METRES_PER_UNIT:
        raise BadInputError(f"unsupported $INSUNITS code {insunits}", file=source, field="$INSUNITS")
    return insunits


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


# ----------------------------------------------------------------------------------------------- extents


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
