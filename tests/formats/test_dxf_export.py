"""Tests of driftmap.formats.dxf_export: the drawing read back by ezdxf (and by driftmap's survey reader)."""

from __future__ import annotations

import io
import math

import ezdxf
import pytest

from driftmap.formats.csv_exports import PoseRow
from driftmap.formats.dxf_export import (
    CLOSURES_LAYER,
    NODES_LAYER,
    REJECTED_CLOSURES_LAYER,
    ClosureSegment,
    NodeMarks,
    layer_name,
    map_dxf_text,
)
from driftmap.formats.survey_dxf import read_survey_dxf
from driftmap.formats.trajectory_exports import Track, TrackPose, tracks_from_poses

POSES = [
    PoseRow("map-01", 0, 13702.25, 56911.5, 0.3, 0.0),
    PoseRow("map-01", 1, 13703.125, 56912.0, 2.9, 0.1),
    PoseRow("map-01", 2, 13704.0, 56912.75, -3.1, 0.2),
    PoseRow("east:2", 0, 13690.5, 56900.0, -1.2, 0.0),
    PoseRow("east:2", 5, 13691.0, 56899.0, 0.0, 0.5),
]
NODES = NodeMarks([(13700.0, 56910.0), (13705.0, 56913.0), (13690.0, 56900.0)], [(0, 1), (0, 2)])
CLOSURES = [
    ClosureSegment((13702.25, 56911.5), (13690.5, 56900.0), True),
    ClosureSegment((13704.0, 56912.75), (13691.0, 56899.0), False),
]


def _read(text: str) -> ezdxf.document.Drawing:
    return ezdxf.read(io.StringIO(text))


class TestDrawing:
    def test_one_layer_per_drive_holds_its_trajectory(self) -> None:
        doc = _read(map_dxf_text(tracks_from_poses(POSES)))
        assert doc.header["$INSUNITS"] == 6
        msp = doc.modelspace()
        by_layer = {e.dxf.layer: e for e in msp}
        assert set(by_layer) == {"DRIVE-map-01", "DRIVE-east_2"}
        assert {"DRIVE-map-01", "DRIVE-east_2"} <= {layer.dxf.name for layer in doc.layers}
        line = by_layer["DRIVE-map-01"]
        assert line.dxftype() == "LWPOLYLINE" and not line.closed
        assert [tuple(p) for p in line.get_points("xy")] == [(p.x_m, p.y_m) for p in POSES[:3]]
        assert [tuple(p) for p in by_layer["DRIVE-east_2"].get_points("xy")] == [
            (13690.5, 56900.0),
            (13691.0, 56899.0),
        ]
        assert NODES_LAYER not in doc.layers and CLOSURES_LAYER not in doc.layers

    def test_node_and_closure_layers(self) -> None:
        doc = _read(map_dxf_text(tracks_from_poses(POSES), NODES, CLOSURES))
        msp = doc.modelspace()
        points = [tuple(e.dxf.location)[:2] for e in msp.query(f'POINT[layer=="{NODES_LAYER}"]')]
        assert points == list(NODES.centres_m)
        labels = [(e.dxf.text, tuple(e.dxf.insert)[:2]) for e in msp.query(f'TEXT[layer=="{NODES_LAYER}"]')]
        assert labels == [(str(n), xy) for n, xy in enumerate(NODES.centres_m)]
        edges = [
            (tuple(e.dxf.start)[:2], tuple(e.dxf.end)[:2]) for e in msp.query(f'LINE[layer=="{NODES_LAYER}"]')
        ]
        assert edges == [(NODES.centres_m[a], NODES.centres_m[b]) for a, b in NODES.edges]
        kept = [
            (tuple(e.dxf.start)[:2], tuple(e.dxf.end)[:2])
            for e in msp.query(f'LINE[layer=="{CLOSURES_LAYER}"]')
        ]
        assert kept == [(CLOSURES[0].a_xy_m, CLOSURES[0].b_xy_m)]
        assert len(msp.query(f'LINE[layer=="{REJECTED_CLOSURES_LAYER}"]')) == 1

    def test_a_single_pose_is_a_point_and_empty_tracks_are_left_out(self) -> None:
        tracks = [Track("one", "vehicle", (TrackPose(0.0, 1.0, 2.0, None),)), Track("none", "vehicle", ())]
        msp = _read(map_dxf_text(tracks)).modelspace()
        assert [(e.dxftype(), e.dxf.layer) for e in msp] == [("POINT", "VEHICLE-one")]

    def test_driftmap_reads_it_back_as_a_survey_plan(self) -> None:
        text = map_dxf_text(tracks_from_poses(POSES), NODES, CLOSURES)
        plan = read_survey_dxf(text.encode("utf-8"), "map.dxf")
        assert {"DRIVE-map-01", "DRIVE-east_2", NODES_LAYER, CLOSURES_LAYER} <= set(plan.layers)

    def test_non_finite_coordinates_are_refused(self) -> None:
        with pytest.raises(ValueError, match="finite"):
            map_dxf_text(
                [Track("d", "drive", (TrackPose(0.0, math.inf, 0.0, 0.0), TrackPose(1.0, 0.0, 0.0, 0.0)))]
            )


class TestLayerNames:
    def test_forbidden_characters_and_clashes(self) -> None:
        taken: set[str] = set()
        assert layer_name("drive", 'a<b>/c\\d"e:f;g?h*i|j=k`l', taken) == "DRIVE-a_b__c_d_e_f_g_h_i_j_k_l"
        assert layer_name("drive", "x:1", taken) == "DRIVE-x_1"
        assert layer_name("drive", "X;1", taken) == "DRIVE-X_1-2"  # layer names are case-blind
