"""Tests of the DXF reader's bounds and robustness: limits refused fast, CR LF and recovered files, hatches."""

from __future__ import annotations

import io
import math
import time
import tracemalloc
from pathlib import Path
from typing import Any

import pytest
from ezdxf.document import Drawing
from ezdxf.filemanagement import new as new_dxf
from ezdxf.math import Vec3

from driftmap.errors import BadInputError, PayloadTooLargeError
from driftmap.formats.survey_dxf import SAGITTA_M, DxfLimits, read_survey_dxf
from tests.formats.test_survey_dxf import assert_on_circle, coords, dxf_bytes

REFUSAL_S = 10.0  # a plan over a limit is refused within this time, seconds: a guard against the minutes the
# unbounded reader took, not a speed figure (make test runs three test processes on two cores)
REFUSAL_BYTES = 100 * 1024**2  # and with at most this much memory allocated on the way

# one CIRCLE of radius 1e12 in 116 bytes (a 152-byte plan like it took 183 s and 7.8 GB to refuse)
HUGE_CIRCLE = (
    b"  0\nSECTION\n  2\nENTITIES\n  0\nCIRCLE\n  5\n2A\n  8\nWALLS\n 10\n0.0\n 20\n0.0\n 30\n0.0\n"
    b" 40\n1000000000000.0\n  0\nENDSEC\n  0\nEOF\n"
)


def refusal(data: bytes, limits: DxfLimits = DxfLimits()) -> tuple[BadInputError, float, int]:
    """The error ``data`` is refused with, the seconds it took and the peak bytes allocated meanwhile."""
    tracemalloc.start()
    start = time.perf_counter()
    try:
        with pytest.raises(BadInputError) as info:
            read_survey_dxf(data, "plan.dxf", limits)
        elapsed = time.perf_counter() - start
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert info.value.file == "plan.dxf"
    return info.value, elapsed, peak


def drawing(version: str = "R2000") -> tuple[Drawing, Any]:
    doc = new_dxf(version)
    return doc, doc.modelspace()


class TestExtent:
    def test_a_huge_circle_is_refused_at_once(self) -> None:
        error, elapsed, peak = refusal(HUGE_CIRCLE)
        assert type(error) is BadInputError  # 422: the drawing is unusable, not merely big
        assert "CIRCLE #2A on layer 'WALLS'" in error.reason and "survey_max_extent_m" in error.reason
        assert elapsed < REFUSAL_S and peak < REFUSAL_BYTES

    def test_entities_far_apart_are_refused_naming_the_one_that_spreads_it(self) -> None:
        doc, msp = drawing()
        msp.add_line((0, 0), (10, 0), dxfattribs={"layer": "WALLS"})
        far = msp.add_text("far", dxfattribs={"layer": "LABELS", "insert": (0, 150_000)})
        error, _, _ = refusal(dxf_bytes(doc))
        assert f"TEXT #{far.dxf.handle} on layer 'LABELS'" in error.reason

    def test_the_limit_is_in_metres_whatever_the_units(self) -> None:
        doc, msp = drawing()
        doc.header["$INSUNITS"] = 4  # millimetres
        msp.add_line((0, 0), (90_000_000, 0))  # 90 km
        assert read_survey_dxf(dxf_bytes(doc), "mm.dxf").extents[2] == pytest.approx(90_000)
        msp.add_line((0, 0), (0, 110_000_000))
        assert "110 km" not in refusal(dxf_bytes(doc))[0].reason  # a number of metres, not a guess
        assert "1.1e+05 m across" in refusal(dxf_bytes(doc))[0].reason

    def test_a_spline_is_checked_by_its_control_points_before_it_is_flattened(self) -> None:
        doc, msp = drawing()
        msp.add_open_spline([(0, 0), (1e9, 1), (2e9, 0), (3e9, 1)])
        error, elapsed, peak = refusal(dxf_bytes(doc))
        assert "SPLINE" in error.reason and elapsed < REFUSAL_S and peak < REFUSAL_BYTES


class TestPoints:
    def test_a_circle_over_the_curve_limit_is_refused_before_flattening(self) -> None:
        doc, msp = drawing()
        msp.add_circle((0, 0), 40_000, dxfattribs={"layer": "RING"})  # about 2,000 chords of 5 cm sagitta
        limits = DxfLimits(max_curve_points=1000)
        error, elapsed, _ = refusal(dxf_bytes(doc), limits)
        assert isinstance(error, PayloadTooLargeError)
        assert (
            "CIRCLE" in error.reason
            and "'RING'" in error.reason
            and "survey_max_curve_points" in error.reason
        )
        assert elapsed < REFUSAL_S
        assert read_survey_dxf(dxf_bytes(doc), "plan.dxf", DxfLimits(max_curve_points=3000)).layers["RING"]

    @pytest.mark.parametrize("kind", ["LWPOLYLINE", "SPLINE", "ELLIPSE", "HATCH"])
    def test_other_curves_stop_at_the_curve_limit(self, kind: str) -> None:
        doc, msp = drawing()
        wiggle = [(float(k), float(k % 2)) for k in range(400)]
        if kind == "LWPOLYLINE":
            msp.add_lwpolyline(wiggle)
        elif kind == "SPLINE":
            msp.add_open_spline(wiggle)
        elif kind == "ELLIPSE":
            msp.add_ellipse((0, 0), major_axis=(40_000, 0), ratio=0.5)
        else:
            msp.add_hatch().paths.add_polyline_path(wiggle)
        error, elapsed, _ = refusal(dxf_bytes(doc), DxfLimits(max_curve_points=300))
        assert isinstance(error, PayloadTooLargeError) and kind in error.reason
        assert elapsed < REFUSAL_S

    def test_the_plan_stops_at_the_total_limit(self) -> None:
        doc, msp = drawing()
        for k in range(100):
            msp.add_line((0, k), (10, k))
        assert read_survey_dxf(dxf_bytes(doc), "plan.dxf", DxfLimits(max_points=200)).layers["0"]
        error, _, _ = refusal(dxf_bytes(doc), DxfLimits(max_points=199))
        assert isinstance(error, PayloadTooLargeError) and "survey_max_points" in error.reason
        assert "flattens to more than 199 points" in error.reason  # not caught by the count before parsing

    @pytest.mark.parametrize("end", ["\n", "\r\n"])
    def test_a_big_file_over_the_total_limit_is_refused_before_it_is_parsed(self, end: str) -> None:
        """1.2 million vertices in 12,000 polylines, 30 MB (such a file took 20 s and 430 MB to parse)."""
        vertices = "".join(f" 10{end}{k}.125{end} 20{end}{k % 7}.5{end}" for k in range(100))
        polyline = f"  0{end}LWPOLYLINE{end}  8{end}WALLS{end} 90{end}100{end}{vertices}"
        data = (
            f"  0{end}SECTION{end}  2{end}ENTITIES{end}{polyline * 12_000}  0{end}ENDSEC{end}  0{end}EOF{end}"
        )
        error, elapsed, peak = refusal(data.encode())
        assert isinstance(error, PayloadTooLargeError) and "1200000 coordinates" in error.reason
        assert elapsed < REFUSAL_S and peak < REFUSAL_BYTES


class TestEntities:
    def test_nested_blocks_that_multiply_are_refused(self) -> None:
        """Ten references of ten references ... twelve deep: 10^12 lines from a few kilobytes."""
        doc, msp = drawing()
        doc.blocks.new("B0").add_line((0, 0), (1, 0))
        for depth in range(1, 13):
            block = doc.blocks.new(f"B{depth}")
            for k in range(10):
                block.add_blockref(f"B{depth - 1}", (0, k * 1e-6))
        msp.add_blockref("B12", (0, 0))
        error, elapsed, peak = refusal(dxf_bytes(doc))
        assert isinstance(error, PayloadTooLargeError) and "survey_max_entities" in error.reason
        assert "1e+12 entities" in error.reason
        assert elapsed < REFUSAL_S and peak < REFUSAL_BYTES

    def test_a_huge_minsert_grid_is_refused(self) -> None:
        doc, msp = drawing()
        doc.blocks.new("DOT").add_point((0, 0))
        msp.add_blockref("DOT", (0, 0)).grid(size=(1_000_000, 1_000_000), spacing=(1e-3, 1e-3))
        error, elapsed, peak = refusal(dxf_bytes(doc))
        assert isinstance(error, PayloadTooLargeError) and elapsed < REFUSAL_S and peak < REFUSAL_BYTES

    def test_a_file_over_the_size_limit_is_refused_unread(self) -> None:
        doc, msp = drawing()
        msp.add_line((0, 0), (1, 0))
        data = dxf_bytes(doc)
        error, _, _ = refusal(data, DxfLimits(max_file_bytes=len(data) - 1))
        assert isinstance(error, PayloadTooLargeError) and "survey_max_file_bytes" in error.reason


def plan_with_binary_data() -> str:
    """A plan holding binary data (group code 310, as thumbnails and proxy graphics do), as DXF text."""
    doc, msp = drawing()
    msp.add_line((0, 0), (10, 0), dxfattribs={"layer": "WALLS"})
    doc.objects.add_xrecord(doc.rootdict.dxf.handle).reset([(310, bytes(range(64)))])
    stream = io.StringIO()
    doc.write(stream)
    return stream.getvalue()


class TestReading:
    @pytest.mark.parametrize("end", ["\r\n", "\r"])
    def test_windows_and_old_mac_line_ends(self, end: str) -> None:
        # CR LF files with binary data were refused as "Invalid binary data"; without, read as empty
        survey = read_survey_dxf(plan_with_binary_data().replace("\n", end).encode(), "win.dxf")
        assert coords(survey, "WALLS") == [[0.0, 0.0], [10.0, 0.0]]

    def test_a_file_the_strict_reader_refuses_is_recovered(self) -> None:
        text = plan_with_binary_data().replace("\n 10\n0.0\n 20\n0.0\n", "\n 10\n0.0 \n 20\n  0.0m\n", 1)
        with pytest.raises(Exception, match="floating point"):  # what the strict reader says
            from ezdxf.filemanagement import read

            read(io.StringIO(text))
        survey = read_survey_dxf(text.encode(), "messy.dxf")
        assert coords(survey, "WALLS") == [[0.0, 0.0], [10.0, 0.0]]

    def test_binary_dxf_with_binary_data(self, tmp_path: Path) -> None:
        doc, msp = drawing("R2018")
        msp.add_circle((5, 5), 2, dxfattribs={"layer": "RING"})
        doc.objects.add_xrecord(doc.rootdict.dxf.handle).reset([(310, bytes(range(256)))])
        doc.saveas(tmp_path / "bin.dxf", fmt="bin")
        survey = read_survey_dxf((tmp_path / "bin.dxf").read_bytes(), "bin.dxf")
        assert_on_circle(coords(survey, "RING"), (5, 5), 2)

    def test_insunits_that_is_not_a_number(self) -> None:
        text = plan_with_binary_data().replace("$INSUNITS\n 70\n", "$INSUNITS\n  1\n", 1)
        if "$INSUNITS" not in text:
            pytest.skip("no $INSUNITS written")
        with pytest.raises(BadInputError) as info:
            read_survey_dxf(text.replace("$INSUNITS\n  1\n6\n", "$INSUNITS\n  1\nmetres\n").encode(), "u.dxf")
        assert info.value.field == "$INSUNITS"


class TestHatches:
    def test_edge_path_of_line_arc_ellipse_and_spline(self) -> None:
        doc, msp = drawing()
        hatch = msp.add_hatch(dxfattribs={"layer": "FILL"})
        edges = hatch.paths.add_edge_path()
        edges.add_line((0, 0), (10, 0))
        edges.add_arc((10, 5), 5, -90, 90)  # (10, 0) round to (10, 10)
        edges.add_ellipse((5, 10), major_axis=(5, 0), ratio=0.4, start_angle=0, end_angle=180)
        edges.add_spline(control_points=[(0, 10), (-2, 5), (0, 0)], degree=2)
        survey = read_survey_dxf(dxf_bytes(doc), "fill.dxf")
        [feature] = survey.layers["FILL"].features["features"]
        points = feature["geometry"]["coordinates"]
        assert feature["properties"] == {"entity": "HATCH", "closed": True} and points[0] == points[-1]
        arc = [p for p in points if p[0] > 10 + 1e-9]
        assert len(arc) > 5
        for x, y in arc:
            assert math.hypot(x - 10, y - 5) == pytest.approx(5, abs=SAGITTA_M + 1e-3)
        assert min(x for x, _ in points) == pytest.approx(-1, abs=0.1)  # the spline bulges to x = -1

    def test_polyline_path_with_a_bulge_and_several_boundaries(self) -> None:
        doc, msp = drawing()
        hatch = msp.add_hatch(dxfattribs={"layer": "FILL"})
        hatch.paths.add_polyline_path([(0, 0, 0), (10, 0, 1), (10, 10, 0)], is_closed=True)  # a half circle
        hatch.paths.add_polyline_path([(20, 0), (21, 0), (21, 1)])
        survey = read_survey_dxf(dxf_bytes(doc), "fill.dxf")
        assert survey.layers["FILL"].counts == {"HATCH": 2}
        assert max(x for x, _ in coords(survey, "FILL")) == pytest.approx(15, abs=1e-3)

    def test_hatch_with_a_downward_extrusion_and_in_a_block(self) -> None:
        doc, msp = drawing()
        mirrored = msp.add_hatch(dxfattribs={"layer": "OCS", "extrusion": (0, 0, -1)})
        mirrored.paths.add_polyline_path([(1, 1), (2, 1), (2, 2)])
        block = doc.blocks.new("FILLED")
        block.add_hatch().paths.add_polyline_path([(0, 0), (1, 0), (1, 1)])
        msp.add_blockref("FILLED", (100, 0), dxfattribs={"layer": "BLOCKS", "rotation": 90})
        survey = read_survey_dxf(dxf_bytes(doc), "fill.dxf")
        assert coords(survey, "OCS")[:3] == [[-1, 1], [-2, 1], [-2, 2]]  # OCS x points west
        assert [
            Vec3(*p, 0).isclose(Vec3(q))
            for p, q in zip(coords(survey, "BLOCKS"), [(100, 0), (100, 1), (99, 1)], strict=False)
        ] == [True] * 3
