"""Tests of driftmap.formats.survey_dxf: plans drawn with ezdxf inside the tests, R12 to R2018."""

from __future__ import annotations

import io
import itertools
import json
import math
from pathlib import Path
from typing import Any

import pytest
from ezdxf.document import Drawing
from ezdxf.filemanagement import new as new_dxf

from driftmap.errors import BadInputError
from driftmap.formats.survey_dxf import SAGITTA_M, read_survey_dxf, survey_map_from_json, survey_map_to_json

COORD_TOL_M = 1e-9  # exact transforms (lines, block references)
CURVE_TOL_M = SAGITTA_M + 1e-6  # flattened curves stay this close to the true curve
VERSIONS = ["R12", "R2000", "R2018"]


def dxf_bytes(doc: Drawing) -> bytes:
    stream = io.StringIO()
    doc.write(stream)
    return stream.getvalue().encode(doc.encoding)


def draw_plan(version: str) -> Drawing:
    """One entity of each supported kind, each on its own layer; the newer ones only from R2000."""
    doc = new_dxf(version)
    msp = doc.modelspace()
    msp.add_line((0, 0), (10, 0), dxfattribs={"layer": "WALLS"})
    msp.add_polyline2d([(0, 10), (4, 10), (4, 14)], close=True, dxfattribs={"layer": "POLY2D"})
    msp.add_polyline3d([(0, 20, 5), (3, 24, 7)], dxfattribs={"layer": "POLY3D"})
    msp.add_arc((20, 0), 5, 0, 90, dxfattribs={"layer": "ARCS"})
    msp.add_circle((30, 30), 2, dxfattribs={"layer": "CIRCLES"})
    msp.add_text("DP1", height=1.5, dxfattribs={"layer": "LABELS", "insert": (5, 6)})
    block = doc.blocks.new("DRAWPOINT")
    block.add_line((0, 0), (1, 0))  # layer 0: takes the layer of the reference
    block.add_circle((0, 0), 0.5, dxfattribs={"layer": "DP_RING"})
    outer = doc.blocks.new("PAIR")
    outer.add_blockref("DRAWPOINT", (10, 0))
    msp.add_blockref(
        "DRAWPOINT", (100, 200), dxfattribs={"layer": "DRAWPOINTS", "rotation": 90, "xscale": 2, "yscale": 2}
    )
    msp.add_blockref("PAIR", (0, -50), dxfattribs={"layer": "PAIRS", "rotation": 180})
    if version != "R12":
        msp.add_lwpolyline([(0, 40, 1.0), (10, 40, 0)], format="xyb", dxfattribs={"layer": "BULGE"})
        msp.add_lwpolyline(
            [(50, 50), (60, 50), (60, 60), (50, 60)], close=True, dxfattribs={"layer": "SQUARE"}
        )
        msp.add_ellipse((40, 0), major_axis=(4, 0), ratio=0.5, dxfattribs={"layer": "ELLIPSES"})
        msp.add_spline([(0, 70), (5, 75), (10, 70), (15, 75)], dxfattribs={"layer": "SPLINES"})
        msp.add_mtext("Drive 7", dxfattribs={"layer": "LABELS", "insert": (7, 8)})
        msp.add_hatch(dxfattribs={"layer": "HATCH"}).paths.add_polyline_path([(0, 0), (1, 0), (1, 1)])
    return doc


def coords(survey: Any, layer: str, index: int = 0) -> list[list[float]]:
    return survey.layers[layer].features["features"][index]["geometry"]["coordinates"]  # type: ignore[no-any-return]


@pytest.fixture(scope="module", params=VERSIONS)
def version(request: pytest.FixtureRequest) -> str:
    return str(request.param)


@pytest.fixture(scope="module")
def plan(version: str) -> Any:
    return read_survey_dxf(dxf_bytes(draw_plan(version)), f"plan-{version}.dxf")


class TestEntities:
    def test_line(self, plan: Any) -> None:
        assert coords(plan, "WALLS") == [[0.0, 0.0], [10.0, 0.0]]
        assert plan.layers["WALLS"].features["features"][0]["properties"] == {
            "entity": "LINE",
            "closed": False,
        }

    def test_closed_2d_polyline_repeats_its_first_point(self, plan: Any) -> None:
        assert coords(plan, "POLY2D") == [[0, 10], [4, 10], [4, 14], [0, 10]]
        assert plan.layers["POLY2D"].features["features"][0]["properties"]["closed"] is True

    def test_3d_polyline_drops_z(self, plan: Any) -> None:
        assert coords(plan, "POLY3D") == [[0, 20], [3, 24]]

    def test_arc_is_flattened_within_the_sagitta(self, plan: Any) -> None:
        points = coords(plan, "ARCS")
        assert points[0] == pytest.approx([25, 0], abs=COORD_TOL_M)
        assert points[-1] == pytest.approx([20, 5], abs=COORD_TOL_M)
        assert_on_circle(points, (20, 0), 5)

    def test_circle_is_a_closed_ring(self, plan: Any) -> None:
        points = coords(plan, "CIRCLES")
        assert points[0] == points[-1] and len(points) > 8
        assert_on_circle(points, (30, 30), 2)

    def test_text_is_a_point_with_its_text(self, plan: Any) -> None:
        features = plan.layers["LABELS"].features["features"]
        texts = {f["properties"]["text"]: f for f in features}
        assert texts["DP1"]["geometry"] == {"type": "Point", "coordinates": [5.0, 6.0]}
        assert texts["DP1"]["properties"]["height_m"] == 1.5  # the browser draws it this high

    def test_block_reference_is_rotated_scaled_and_moved(self, plan: Any) -> None:
        # block LINE (0,0)-(1,0) on layer 0, rotated 90 degrees, scaled 2, at (100, 200)
        assert flat(coords(plan, "DRAWPOINTS")) == pytest.approx([100, 200, 100, 202], abs=COORD_TOL_M)
        ring = coords(plan, "DP_RING")
        assert_on_circle(ring, (100, 200), 1.0)

    def test_nested_block_reference(self, plan: Any) -> None:
        # PAIR holds DRAWPOINT at (10, 0); PAIR is rotated 180 degrees at (0, -50)
        assert flat(coords(plan, "PAIRS")) == pytest.approx([-10, -50, -11, -50], abs=COORD_TOL_M)

    def test_counts_and_extents(self, plan: Any) -> None:
        assert plan.layers["DRAWPOINTS"].counts == {"LINE": 1}
        assert plan.layers["WALLS"].extents == (0.0, 0.0, 10.0, 0.0)
        assert plan.layers["CIRCLES"].extents == pytest.approx((28, 28, 32, 32), abs=CURVE_TOL_M)
        min_x, min_y, _max_x, max_y = plan.extents
        assert (min_x, min_y) == pytest.approx((-11, -50.5), abs=CURVE_TOL_M)
        assert max_y == pytest.approx(202, abs=COORD_TOL_M)


@pytest.fixture(scope="module")
def new_plan() -> Any:
    return read_survey_dxf(dxf_bytes(draw_plan("R2018")), "plan.dxf")


class TestNewerEntities:
    def test_bulge_becomes_a_half_circle(self, new_plan: Any) -> None:
        points = coords(new_plan, "BULGE")
        assert points[0] == pytest.approx([0, 40]) and points[-1] == pytest.approx([10, 40])
        assert_on_circle(points, (5, 40), 5, vertex_tol=1e-3)
        assert min(y for _, y in points) == pytest.approx(35)  # positive bulge: counter-clockwise
        assert len(points) > 10

    def test_closed_lwpolyline(self, new_plan: Any) -> None:
        assert coords(new_plan, "SQUARE") == [[50, 50], [60, 50], [60, 60], [50, 60], [50, 50]]

    def test_ellipse_points_lie_on_the_ellipse(self, new_plan: Any) -> None:
        points = coords(new_plan, "ELLIPSES")
        assert points[0] == points[-1]
        for x, y in points:
            assert ((x - 40) / 4) ** 2 + (y / 2) ** 2 == pytest.approx(1, abs=0.03)

    def test_spline_passes_through_its_end_fit_points(self, new_plan: Any) -> None:
        points = coords(new_plan, "SPLINES")
        assert points[0] == pytest.approx([0, 70], abs=1e-6) and points[-1] == pytest.approx(
            [15, 75], abs=1e-6
        )
        assert len(points) > 10

    def test_mtext(self, new_plan: Any) -> None:
        features = new_plan.layers["LABELS"].features["features"]
        assert features[1]["properties"] == {"text": "Drive 7", "entity": "MTEXT", "height_m": 2.5}
        assert features[1]["geometry"]["coordinates"] == [7.0, 8.0]

    def test_hatch_boundary_is_a_closed_line(self, new_plan: Any) -> None:
        assert coords(new_plan, "HATCH") == [[0, 0], [1, 0], [1, 1], [0, 0]]
        assert new_plan.layers["HATCH"].features["features"][0]["properties"] == {
            "entity": "HATCH",
            "closed": True,
        }
        assert new_plan.skipped == {}

    def test_attributes_of_a_block_reference_become_text(self) -> None:
        doc = new_dxf("R2000")
        block = doc.blocks.new("TAG")
        block.add_line((0, 0), (1, 1))
        block.add_attdef("NAME", (0, 1))
        doc.modelspace().add_blockref("TAG", (10, 10)).add_auto_attribs({"NAME": "DP-12"})
        survey = read_survey_dxf(dxf_bytes(doc), "tag.dxf")
        texts = [f for f in survey.layers["0"].features["features"] if f["geometry"]["type"] == "Point"]
        assert [f["properties"]["text"] for f in texts] == ["DP-12"]
        assert texts[0]["geometry"]["coordinates"] == [10.0, 11.0]


class TestUnits:
    @pytest.mark.parametrize(
        ("code", "scale"), [(0, 1.0), (6, 1.0), (4, 1e-3), (5, 1e-2), (2, 0.3048), (1, 0.0254)]
    )
    def test_insunits_scale_to_metres(self, code: int, scale: float) -> None:
        doc = new_dxf("R2000")
        doc.header["$INSUNITS"] = code
        doc.modelspace().add_line((1000, 2000), (3000, 2000))
        doc.modelspace().add_circle((0, 0), 1000)
        survey = read_survey_dxf(dxf_bytes(doc), "mm.dxf")
        assert (survey.insunits, survey.metres_per_unit) == (code, scale)
        assert flat(coords(survey, "0")) == pytest.approx(
            [1000 * scale, 2000 * scale, 3000 * scale, 2000 * scale]
        )
        assert_on_circle(coords(survey, "0", 1), (0, 0), 1000 * scale)

    def test_unknown_units_are_refused(self) -> None:
        doc = new_dxf("R2000")
        doc.header["$INSUNITS"] = 19  # light years
        doc.modelspace().add_line((0, 0), (1, 0))
        with pytest.raises(BadInputError) as info:
            read_survey_dxf(dxf_bytes(doc), "space.dxf")
        assert (info.value.file, info.value.field) == ("space.dxf", "$INSUNITS")


class TestBadFiles:
    def error(self, data: bytes) -> BadInputError:
        with pytest.raises(BadInputError) as info:
            read_survey_dxf(data, "plan.dxf")
        assert info.value.file == "plan.dxf"
        return info.value

    def test_empty_drawing(self) -> None:
        assert "no drawable entities" in self.error(dxf_bytes(new_dxf("R2000"))).reason

    def test_only_undrawable_entities(self) -> None:
        doc = new_dxf("R2000")
        doc.modelspace().add_3dface([(0, 0, 0), (1, 0, 0), (1, 1, 1)])
        assert "1 3DFACE" in self.error(dxf_bytes(doc)).reason

    @pytest.mark.parametrize(
        "data", [b"", b"hello world\n", bytes(range(256)) * 4, b"%PDF-1.4\n" + b"x" * 100]
    )
    def test_garbage(self, data: bytes) -> None:
        self.error(data)

    @pytest.mark.parametrize("keep", [0.3, 0.5, 0.99])
    def test_truncated(self, keep: float) -> None:
        data = dxf_bytes(draw_plan("R2000"))
        assert "truncated" in self.error(data[: int(len(data) * keep)]).reason

    def test_malformed_tag_reports_the_line(self) -> None:
        text = dxf_bytes(draw_plan("R2000")).decode()
        lines = text.split("\n")
        index = lines.index("LINE") - 1  # the group code 0 before LINE
        lines[index] = "zero"
        assert f"line {index + 1}" in self.error("\n".join(lines).encode()).reason

    def test_binary_garbage_after_the_magic(self) -> None:
        assert "binary DXF" in self.error(b"AutoCAD Binary DXF\r\n\x1a\x00" + b"\xff" * 50).reason


class TestEncodingsAndBinary:
    def test_cp1252_text(self) -> None:
        doc = new_dxf("R12")
        doc.modelspace().add_text("Schacht Süd", dxfattribs={"insert": (1, 2)})
        stream = io.StringIO()
        doc.write(stream)
        survey = read_survey_dxf(stream.getvalue().encode("cp1252"), "old.dxf")
        assert survey.layers["0"].features["features"][0]["properties"]["text"] == "Schacht Süd"

    def test_binary_dxf(self, tmp_path: Path) -> None:
        doc = draw_plan("R2000")
        doc.saveas(tmp_path / "bin.dxf", fmt="bin")
        survey = read_survey_dxf((tmp_path / "bin.dxf").read_bytes(), "bin.dxf")
        assert coords(survey, "WALLS") == [[0.0, 0.0], [10.0, 0.0]]


class TestJson:
    def test_round_trip_through_json_text(self, plan: Any) -> None:
        text = json.dumps(survey_map_to_json(plan), allow_nan=False)
        back = survey_map_from_json(
            json.loads(text),
            source=plan.source,
            insunits=plan.insunits,
            metres_per_unit=plan.metres_per_unit,
            skipped=plan.skipped,
        )
        assert back == plan

    def test_layer_names_map_to_feature_collections(self, plan: Any) -> None:
        obj = survey_map_to_json(plan)
        assert sorted(obj) == sorted(plan.layers)
        assert all(layer["type"] == "FeatureCollection" for layer in obj.values())
        assert obj["WALLS"]["extents"] == [0.0, 0.0, 10.0, 0.0] and obj["WALLS"]["counts"] == {"LINE": 1}

    @pytest.mark.parametrize("obj", [{}, {"WALLS": 3}, {"WALLS": {"type": "Feature"}}, [1]])
    def test_damaged_json(self, obj: Any) -> None:
        with pytest.raises(BadInputError, match="damaged"):
            survey_map_from_json(obj)


def flat(points: list[list[float]]) -> list[float]:
    return [c for p in points for c in p]


def assert_on_circle(
    points: list[list[float]], centre: tuple[float, float], radius: float, vertex_tol: float = 1e-9
) -> None:
    """Every vertex on the circle and every chord midpoint within the sagitta tolerance of it."""
    for x, y in points:
        assert math.hypot(x - centre[0], y - centre[1]) == pytest.approx(
            radius, abs=vertex_tol * max(radius, 1)
        )
    for (x0, y0), (x1, y1) in itertools.pairwise(points):
        mid = math.hypot((x0 + x1) / 2 - centre[0], (y0 + y1) / 2 - centre[1])
        assert radius - mid <= CURVE_TOL_M
