"""The synthetic level: graph structure, geometry, sizes, determinism and the survey DXF."""

from __future__ import annotations

from pathlib import Path

import ezdxf
import numpy as np
import pytest
from shapely.geometry import LineString

from driftmap.formats.survey_dxf import read_survey_dxf
from driftmap.sim.layout import Layout, generate_layout
from driftmap.sim.params import SIZES
from driftmap.sim.survey import write_survey_dxf

LENGTH_TOLERANCE = 0.25  # sizes within 25 % of their nominal centreline length
NOMINAL_LENGTH_M = {"tiny": 100.0, "small": 400.0, "medium": 1500.0, "large": 6000.0, "mine": 20000.0}


@pytest.fixture(scope="module", params=["tiny", "small", "medium"])
def layout(request: pytest.FixtureRequest) -> Layout:
    return generate_layout(11, SIZES[request.param])


class TestGraph:
    def test_junctions_cycle_drawpoints_and_dump(self, layout: Layout) -> None:
        assert any(layout.degree(n.id) >= 3 for n in layout.nodes_of_kind("junction"))
        assert layout.cycle_rank() >= 1
        assert layout.nodes_of_kind("drawpoint")
        assert [n.name for n in layout.nodes_of_kind("dump")] == ["DUMP"]

    def test_dead_ends_have_degree_one_and_junctions_three(self, layout: Layout) -> None:
        for n in layout.nodes:
            assert layout.degree(n.id) == 1 if n.kind != "junction" else layout.degree(n.id) >= 3

    def test_edges_run_from_node_a_to_node_b(self, layout: Layout) -> None:
        for e in layout.edges:
            assert np.allclose(e.polyline[0], layout.nodes[e.a].xy, atol=1e-6)
            assert np.allclose(e.polyline[-1], layout.nodes[e.b].xy, atol=1e-6)

    def test_drawpoints_are_short_side_drives(self, layout: Layout) -> None:
        for e in layout.edges:
            if e.kind == "drawpoint":
                assert layout.nodes[e.b].kind == "drawpoint"
                assert 8.0 <= e.length_m <= 20.0


class TestGeometry:
    def test_mine_grid_coordinates(self, layout: Layout) -> None:
        xy = np.array([n.xy for n in layout.nodes])
        assert np.all((xy[:, 0] > 10_000) & (xy[:, 0] < 20_000))
        assert np.all((xy[:, 1] > 50_000) & (xy[:, 1] < 60_000))

    def test_widths_and_height(self, layout: Layout) -> None:
        assert all(5.0 <= e.width_m <= 6.0 for e in layout.edges)
        assert layout.height_m == pytest.approx(5.0)

    def test_centrelines_lie_inside_the_walls(self, layout: Layout) -> None:
        inner = layout.outline.buffer(-2.0)
        for e in layout.edges:
            line = LineString(e.polyline)
            assert inner.buffer(0.01).covers(line.interpolate(0.5, normalized=True))
        assert layout.outline.is_valid and len(layout.walls) == 1 + len(layout.outline.interiors)

    def test_a_loop_makes_a_pillar(self, layout: Layout) -> None:
        assert len(layout.outline.interiors) >= 1  # a hole in the outline: the pillar inside a loop

    @pytest.mark.parametrize("size", list(NOMINAL_LENGTH_M))
    def test_sizes(self, size: str) -> None:
        length = generate_layout(3, SIZES[size]).total_length_m
        assert abs(length - NOMINAL_LENGTH_M[size]) <= LENGTH_TOLERANCE * NOMINAL_LENGTH_M[size]


class TestDeterminism:
    def test_same_seed_same_layout(self) -> None:
        a, b = generate_layout(4, SIZES["small"]), generate_layout(4, SIZES["small"])
        assert [n.xy for n in a.nodes] == [n.xy for n in b.nodes]
        assert all(np.array_equal(p, q) for p, q in zip(a.walls, b.walls, strict=True))

    def test_other_seed_other_layout(self) -> None:
        a, b = generate_layout(4, SIZES["small"]), generate_layout(5, SIZES["small"])
        assert a.nodes[0].xy != b.nodes[0].xy


class TestSurveyDxf:
    def test_layers_units_and_entities(self, layout: Layout, tmp_path: Path) -> None:
        path = tmp_path / "survey.dxf"
        write_survey_dxf(layout, path)
        doc = ezdxf.readfile(path)
        assert doc.header["$INSUNITS"] == 6
        msp = doc.modelspace()
        walls = msp.query('LWPOLYLINE[layer=="WALLS"]')
        assert len(walls) == len(layout.walls) and all(w.closed for w in walls)
        assert len(msp.query('LWPOLYLINE[layer=="CENTRELINE"]')) == len(layout.edges)
        drawpoints = layout.nodes_of_kind("drawpoint")
        assert len(msp.query('CIRCLE[layer=="DRAWPOINTS"]')) == len(drawpoints) + 1  # and the dump
        labels = {t.dxf.text for t in msp.query('TEXT[layer=="LABELS"]')}
        assert {"DUMP", *(n.name for n in drawpoints)} <= labels

    def test_read_by_the_survey_importer(self, layout: Layout, tmp_path: Path) -> None:
        path = tmp_path / "survey.dxf"
        write_survey_dxf(layout, path)
        survey = read_survey_dxf(path.read_bytes(), "survey.dxf")
        assert {"WALLS", "CENTRELINE", "DRAWPOINTS"} <= set(survey.layers)
        assert survey.metres_per_unit == 1.0

    def test_byte_identical_per_layout(self, tmp_path: Path) -> None:
        lay = generate_layout(8, SIZES["tiny"])
        write_survey_dxf(lay, tmp_path / "a.dxf")
        write_survey_dxf(generate_layout(8, SIZES["tiny"]), tmp_path / "b.dxf")
        assert (tmp_path / "a.dxf").read_bytes() == (tmp_path / "b.dxf").read_bytes()
