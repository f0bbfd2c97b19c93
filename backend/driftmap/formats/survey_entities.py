"""The drawable entities of a DXF survey plan as GeoJSON-like features, read within :class:`DxfLimits`.

What each entity kind becomes is described in :mod:`driftmap.formats.survey_dxf`. This module walks model
space (block references exploded), flattens curves and bounds the cost of doing so: every entity's
bounding box (from its centre and radius or its control points, before a single point is computed) must
keep the drawing within :attr:`DxfLimits.max_extent_m`, an arc's segment count is computed before it is
flattened, and flattening stops as soon as a curve or the plan passes its point limit. A plan beyond a limit
is refused with an error naming the entity (type, handle, layer) and the setting.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from itertools import islice
from typing import Any, TypeVar

from ezdxf import path as ezpath
from ezdxf.document import Drawing
from ezdxf.entities.dxfgfx import DXFGraphic
from ezdxf.entities.insert import Insert
from ezdxf.math import Vec3, arc_angle_span_deg, arc_segment_count

from driftmap.errors import BadInputError, DriftmapError, PayloadTooLargeError

SAGITTA_M = 0.05  # largest distance between a flattened curve and its chords, metres
MIN_CURVE_SEGMENTS = 16  # ellipses, splines and Bezier pieces are cut into at least this many chords
_MAX_BLOCK_DEPTH = 16  # nested block references deeper than this are taken as a cycle
_LINES = frozenset({"LINE", "LWPOLYLINE", "POLYLINE"})
_TEXTS = frozenset({"TEXT", "MTEXT", "ATTRIB"})
_HATCHES = frozenset({"HATCH", "MPOLYGON"})

Feature = dict[str, Any]
_Entity = TypeVar("_Entity", bound=DXFGraphic)
Box = tuple[float, float, float, float]  # (min_x, min_y, max_x, max_y), metres


@dataclass(frozen=True)
class DxfLimits:
    """What reading and storing one survey plan may cost (server settings ``survey_max_*``)."""

    max_file_bytes: int = 64 * 1024**2  # largest DXF file, bytes
    max_entities: int = 500_000  # entities read, those of a block counted again for every reference
    max_extent_m: float = 100_000.0  # largest side of the drawing's bounding box, metres
    max_curve_points: int = 100_000  # points of one flattened entity or hatch boundary
    max_points: int = 1_000_000  # points of the whole plan
    max_stored_bytes: int = 128 * 1024**2  # JSON of the parsed plan and its first-view levels, bytes


DEFAULT_LIMITS = DxfLimits()


class _DamagedEntityError(Exception):
    """An entity that cannot be drawn (broken data, non-finite coordinates): left out and counted."""


class EntityReader:
    """Turns a document's model space into features, keeping count against the limits.

    Args:
        scale: metres per drawing unit.
        limits: the bounds to enforce.
        source: the file name, for messages.
    """

    def __init__(self, scale: float, limits: DxfLimits, source: str) -> None:
        self.scale = scale
        self.limits = limits
        self.source = source
        self.sagitta = SAGITTA_M / scale  # drawing units
        self.skipped: Counter[str] = Counter()
        self._entities = 0
        self._points = 0
        self._box: Box | None = None

    def features(self, doc: Drawing) -> Iterator[tuple[str, str, Feature]]:
        """(layer, DXF type, feature) for each drawable entity of model space, blocks exploded.

        Raises:
            PayloadTooLargeError: block references that would expand to more than ``max_entities``
                entities (counted from the block definitions before any is exploded), or a limit on points.
            BadInputError: a drawing wider than ``max_extent_m``.
        """
        expanded = expanded_entity_count(doc)
        if expanded > self.limits.max_entities:
            self._too_many_entities(f"expands to {expanded:.3g} entities")
        for entity in doc.modelspace():
            yield from self._entity(entity, entity.dxf.layer, 0)

    # ------------------------------------------------------------------------------------------ walking

    def _entity(self, entity: DXFGraphic, layer: str, depth: int) -> Iterator[tuple[str, str, Feature]]:
        self._entities += 1
        if self._entities > self.limits.max_entities:
            self._too_many_entities(f"expands to more than {self.limits.max_entities} entities")
        dxftype = entity.dxftype()
        if dxftype == "INSERT":
            yield from self._insert(entity, layer, depth)  # type: ignore[arg-type]
            return
        try:
            features = self._geometry(entity, dxftype)
        except DriftmapError:
            raise
        except Exception:  # a damaged entity is left out, not the whole plan
            features = []
        if not features:
            self.skipped[dxftype] += 1
        for feature in features:
            yield layer, dxftype, feature

    def _insert(self, insert: Insert, layer: str, depth: int) -> Iterator[tuple[str, str, Feature]]:
        if depth >= _MAX_BLOCK_DEPTH:
            self.skipped["INSERT"] += 1
            return
        singles: Iterator[Insert] = insert.multi_insert() if insert.mcount > 1 else iter([insert])
        for single in _safely(singles, self.skipped):  # lazily: the entity limit stops a huge MINSERT grid
            for child in _safely(single.virtual_entities(), self.skipped):
                child_layer = layer if child.dxf.layer == "0" else child.dxf.layer
                yield from self._entity(child, child_layer, depth + 1)
            for attrib in single.attribs:
                yield from self._entity(attrib, attrib.dxf.layer, depth + 1)

    # ------------------------------------------------------------------------------------------ geometry

    def _geometry(self, entity: DXFGraphic, dxftype: str) -> list[Feature]:
        if dxftype in _LINES or dxftype in ("ARC", "CIRCLE", "ELLIPSE", "SPLINE"):
            if dxftype == "POLYLINE" and (entity.is_poly_face_mesh or entity.is_polygon_mesh):  # type: ignore[attr-defined]
                return []
            points = self._curve(entity, dxftype)
            closed = _is_closed(entity, dxftype)
            return [self._line_feature(points, dxftype, closed)]
        if dxftype in _HATCHES:
            features = []
            for boundary in ezpath.from_hatch(entity):  # type: ignore[arg-type]
                self._check_box(_control_box(boundary.control_vertices()), entity)
                points = self._flatten(entity, boundary.flattening(self.sagitta, MIN_CURVE_SEGMENTS))
                features.append(self._line_feature(points, dxftype, True))
            return features
        if dxftype in _TEXTS:
            return [self._text_feature(entity, dxftype)]
        if dxftype == "POINT":
            return [self._point_feature(entity.dxf.location, entity, {"entity": "POINT"})]
        return []

    def _curve(self, entity: DXFGraphic, dxftype: str) -> list[Vec3]:
        """The entity's points in WCS drawing units, its box checked before it is flattened."""
        vertices: Iterable[Vec3]
        if dxftype in ("ARC", "CIRCLE"):  # exact points on the curve, not on a Bezier approximation
            radius = abs(float(entity.dxf.radius))
            centre = entity.ocs().to_wcs(entity.dxf.center)
            self._check_box(
                (centre.x - radius, centre.y - radius, centre.x + radius, centre.y + radius), entity
            )
            span_deg = (
                360.0
                if dxftype == "CIRCLE"
                else arc_angle_span_deg(entity.dxf.start_angle, entity.dxf.end_angle)
            )
            count = arc_segment_count(radius, math.radians(span_deg), self.sagitta)
            if count + 1 > self.limits.max_curve_points:
                self._too_many_points(entity)
            vertices = entity.flattening(self.sagitta)  # type: ignore[attr-defined]
        elif dxftype == "ELLIPSE":
            ellipse = entity.construction_tool()  # type: ignore[attr-defined]
            reach, centre = ellipse.major_axis.magnitude, ellipse.center
            self._check_box((centre.x - reach, centre.y - reach, centre.x + reach, centre.y + reach), entity)
            vertices = ellipse.flattening(self.sagitta, MIN_CURVE_SEGMENTS)
        elif dxftype == "SPLINE":
            spline = entity.construction_tool()  # type: ignore[attr-defined]
            self._check_box(_control_box(spline.control_points), entity)  # a B-spline stays in their hull
            vertices = spline.flattening(self.sagitta, MIN_CURVE_SEGMENTS)
        elif dxftype == "LINE":  # in WCS
            vertices = [Vec3(entity.dxf.start), Vec3(entity.dxf.end)]
            self._check_box(_control_box(vertices), entity)
        else:  # polylines; bulges become cubic Beziers within ~1e-4 of the arc radius
            path = ezpath.make_path(entity)
            self._check_box(_control_box(path.control_vertices()), entity)
            vertices = path.flattening(self.sagitta, MIN_CURVE_SEGMENTS)
        return self._flatten(entity, vertices)

    def _flatten(self, entity: DXFGraphic, vertices: Iterable[Vec3]) -> list[Vec3]:
        points = list(islice(vertices, self.limits.max_curve_points + 1))
        if len(points) > self.limits.max_curve_points:
            self._too_many_points(entity)
        return points

    def _line_feature(self, vertices: list[Vec3], dxftype: str, closed: bool) -> Feature:
        points = [(v.x * self.scale, v.y * self.scale) for v in vertices]
        if closed and points and points[0] != points[-1]:
            points.append(points[0])
        points = [p for i, p in enumerate(points) if i == 0 or p != points[i - 1]]
        if len(points) < 2 or not all(math.isfinite(c) for p in points for c in p):
            raise _DamagedEntityError(dxftype)
        self._add_points(len(points))
        return {
            "type": "Feature",
            "geometry": {"type": "LineString", "coordinates": [list(p) for p in points]},
            "properties": {"entity": dxftype, "closed": bool(closed)},
        }

    def _text_feature(self, entity: DXFGraphic, dxftype: str) -> Feature:
        # MTEXT's insertion point is in world coordinates, TEXT's and ATTRIB's in the entity's OCS
        location = entity.dxf.insert if dxftype == "MTEXT" else entity.ocs().to_wcs(entity.dxf.insert)
        text = entity.plain_text()  # type: ignore[attr-defined]
        if not isinstance(text, str):
            raise _DamagedEntityError(dxftype)
        properties: dict[str, Any] = {"entity": dxftype, "text": text}
        height = float(entity.dxf.get("char_height" if dxftype == "MTEXT" else "height", 0.0)) * self.scale
        if math.isfinite(height) and height > 0:
            properties["height_m"] = height  # the lettering's height: the browser scales the label with it
        if dxftype == "ATTRIB":
            properties["tag"] = entity.dxf.tag
        return self._point_feature(location, entity, properties)

    def _point_feature(self, location: Any, entity: DXFGraphic, properties: dict[str, Any]) -> Feature:
        x, y = float(location[0]), float(location[1])
        self._check_box((x, y, x, y), entity)
        self._add_points(1)
        point = [x * self.scale, y * self.scale]
        return {
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": point},
            "properties": properties,
        }

    # ------------------------------------------------------------------------------------------ limits

    def _check_box(self, box: Box, entity: DXFGraphic) -> None:
        """Grow the drawing's box by ``box`` (drawing units); refuse a drawing grown past the extent limit."""
        s = self.scale
        box = (box[0] * s, box[1] * s, box[2] * s, box[3] * s)
        if not all(math.isfinite(c) for c in box):
            raise _DamagedEntityError(entity.dxftype())
        if self._box is not None:
            box = _union(self._box, box)
        side_m = max(box[2] - box[0], box[3] - box[1])
        if side_m > self.limits.max_extent_m:
            raise BadInputError(
                f"{_describe(entity)} takes the drawing to {side_m:.4g} m across, beyond the "
                f"{self.limits.max_extent_m:g} m extent limit (setting survey_max_extent_m)",
                file=self.source,
            )
        self._box = box

    def _too_many_entities(self, what: str) -> None:
        raise PayloadTooLargeError(
            f"the plan {what}, block contents counted for every reference; the limit is "
            f"{self.limits.max_entities} (setting survey_max_entities)",
            file=self.source,
        )

    def _too_many_points(self, entity: DXFGraphic) -> None:
        raise PayloadTooLargeError(
            f"{_describe(entity)} flattens to more than {self.limits.max_curve_points} points within "
            f"{SAGITTA_M} m (setting survey_max_curve_points)",
            file=self.source,
        )

    def _add_points(self, count: int) -> None:
        self._points += count
        if self._points > self.limits.max_points:
            raise PayloadTooLargeError(
                f"the plan flattens to more than {self.limits.max_points} points (setting survey_max_points)",
                file=self.source,
            )


def expanded_entity_count(doc: Drawing) -> int:
    """Entities of model space with every block reference expanded (MINSERT grids included).

    Counted from the block definitions, each once, so a plan whose references multiply (ten references of
    ten references of ...) is measured without exploding anything. A block that refers to itself counts
    its reference as one entity.
    """
    per_block: dict[str, int] = {}

    def block_count(name: str) -> int:
        if name not in per_block:
            per_block[name] = 0  # while counting: a cycle adds nothing
            block = doc.blocks.get(name)
            per_block[name] = 0 if block is None else sum(entity_count(e) for e in block)
        return per_block[name]

    def entity_count(entity: DXFGraphic) -> int:
        if entity.dxftype() != "INSERT":
            return 1
        insert: Insert = entity  # type: ignore[assignment]
        try:
            grid = max(int(insert.mcount), 1)
        except Exception:  # a damaged grid: exploding it is left to fail, and be counted, later
            grid = 1
        return 1 + len(insert.attribs) + grid * block_count(str(insert.dxf.get("name", "")))

    return sum(entity_count(e) for e in doc.modelspace())


def _safely(entities: Iterator[_Entity], skipped: Counter[str]) -> Iterator[_Entity]:
    """The entities of a block reference until one cannot be made (a missing or broken block)."""
    while True:
        try:
            entity = next(entities)
        except StopIteration:
            return
        except Exception:
            skipped["INSERT"] += 1
            return
        yield entity


def _is_closed(entity: DXFGraphic, dxftype: str) -> bool:
    if dxftype == "CIRCLE":
        return True
    if dxftype == "ELLIPSE":
        return math.isclose(abs(entity.dxf.end_param - entity.dxf.start_param), math.tau, abs_tol=1e-9)
    if dxftype in ("LWPOLYLINE", "SPLINE"):
        return bool(entity.closed)  # type: ignore[attr-defined]
    if dxftype == "POLYLINE":
        return bool(entity.is_closed)  # type: ignore[attr-defined]
    return False


def _control_box(points: Iterable[Any]) -> Box:
    xs, ys = [], []
    for p in points:
        xs.append(float(p[0]))
        ys.append(float(p[1]))
    if not xs:
        raise _DamagedEntityError("no points")
    return (min(xs), min(ys), max(xs), max(ys))


def _union(a: Box, b: Box) -> Box:
    return (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))


def _describe(entity: DXFGraphic) -> str:
    handle = entity.dxf.get("handle")
    where = f" #{handle}" if handle else " (in a block reference)"
    return f"{entity.dxftype()}{where} on layer {entity.dxf.get('layer', '0')!r}"
