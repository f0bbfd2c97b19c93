"""Tests of driftmap.formats.trajectory_exports: every format written, read back by its reader (evo for TUM
and KITTI, json, an XML parser) and compared with what was written."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import shapely.geometry
from evo.tools import file_interface
from fastkml import kml
from pygeoif.geometry import LineString, Point

from driftmap.errors import BadInputError
from driftmap.formats.csv_exports import PoseRow
from driftmap.formats.position_exports import tracks_from_positions
from driftmap.formats.trajectory_exports import (
    COORDINATES_MEMBER,
    PLANE_COORDINATES,
    Track,
    TrackPose,
    geojson_text,
    kitti_text,
    kml_text,
    one_track,
    tracks_from_poses,
    tum_text,
    yaw_quaternion,
)
from tests.formats.test_position_exports import POSITIONS

POSES = [
    PoseRow("map-01", 0, 13702.25, 56911.5, 0.3, 0.0),
    PoseRow("map-01", 1, 13703.125, 56912.0, 2.9, 0.1),
    PoseRow("map-01", 2, 13704.0, 56912.75, -3.1, 0.2),
    PoseRow("map 02", 0, 13690.5, 56900.0, -1.2, 0.0),
    PoseRow("map 02", 5, 13691.0, 56899.0, 0.0, 0.5),
]
PLANE_TOLERANCE_M = 1e-9  # a pose read back through a rotation matrix or quaternion, metres / radians


def _drive(name: str = "map-01") -> Track:
    return next(t for t in tracks_from_poses(POSES) if t.name == name)


class TestTracks:
    def test_poses_become_one_track_per_drive_in_order(self) -> None:
        tracks = tracks_from_poses(POSES)
        assert [(t.name, t.kind, len(t.poses)) for t in tracks] == [
            ("map-01", "drive", 3),
            ("map 02", "drive", 2),
        ]
        assert [p.frame for p in tracks[1].poses] == [0, 5]

    def test_poses_without_time_are_refused(self) -> None:
        with pytest.raises(ValueError, match="no time"):
            tracks_from_poses([PoseRow("d", 0, 0.0, 0.0, 0.0)])

    def test_one_track_formats_name_the_option_that_picks_one(self) -> None:
        with pytest.raises(BadInputError) as caught:
            one_track(tracks_from_poses(POSES), "TUM", "drive")
        assert caught.value.field == "drive" and "'map-01', 'map 02'" in str(caught.value)
        with pytest.raises(BadInputError, match="no poses"):
            one_track([], "KITTI", "vehicle")


class TestTum:
    def test_evo_reads_the_poses_back(self, tmp_path: Path) -> None:
        track = _drive()
        path = tmp_path / "map-01.tum.txt"
        path.write_text(tum_text(track), encoding="utf-8")
        read = file_interface.read_tum_trajectory_file(str(path))
        np.testing.assert_array_equal(read.timestamps, [p.t_s for p in track.poses])
        np.testing.assert_array_equal(read.positions_xyz, [[p.x_m, p.y_m, 0.0] for p in track.poses])
        for pose, matrix in zip(track.poses, read.poses_se3, strict=True):
            assert pose.yaw_rad is not None
            yaw = math.atan2(matrix[1, 0], matrix[0, 0])
            assert abs(math.remainder(yaw - pose.yaw_rad, 2 * math.pi)) < PLANE_TOLERANCE_M
            np.testing.assert_allclose(matrix[2, :3], [0.0, 0.0, 1.0], atol=PLANE_TOLERANCE_M)

    def test_layout_by_the_spec(self) -> None:
        lines = [line for line in tum_text(_drive()).splitlines() if not line.startswith("#")]
        assert all(len(line.split(" ")) == 8 for line in lines)
        t, x, y, z, qx, qy, qz, qw = (float(v) for v in lines[0].split(" "))
        assert (t, x, y, z, qx, qy) == (0.0, 13702.25, 56911.5, 0.0, 0.0, 0.0)
        assert (qz, qw) == yaw_quaternion(0.3)[2:]

    def test_unknown_heading_is_the_identity(self) -> None:
        track = tracks_from_positions(POSITIONS)[0]
        assert tum_text(track).splitlines()[-1].endswith(" 0.0 0.0 0.0 1.0")


class TestKitti:
    def test_evo_reads_the_poses_back(self, tmp_path: Path) -> None:
        track = _drive()
        path = tmp_path / "map-01.kitti.txt"
        path.write_text(kitti_text(track), encoding="utf-8")
        read = file_interface.read_kitti_poses_file(str(path))
        assert read.num_poses == len(track.poses)
        for pose, matrix in zip(track.poses, read.poses_se3, strict=True):
            assert pose.yaw_rad is not None
            c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
            expected = [[c, -s, 0.0, pose.x_m], [s, c, 0.0, pose.y_m], [0.0, 0.0, 1.0, 0.0]]
            np.testing.assert_array_equal(matrix[:3], expected)

    def test_layout_by_the_spec(self) -> None:
        lines = kitti_text(_drive()).splitlines()
        assert len(lines) == 3 and all(len(line.split(" ")) == 12 for line in lines)
        assert [float(v) for v in lines[0].split(" ")[3::4]] == [13702.25, 56911.5, 0.0]


class TestGeoJson:
    def test_structure_and_values_read_back(self) -> None:
        tracks = tracks_from_poses(POSES) + tracks_from_positions(POSITIONS)
        collection = json.loads(geojson_text(tracks, {"site": "north", "map_version": 3}))
        assert collection["type"] == "FeatureCollection"
        assert collection[COORDINATES_MEMBER] == PLANE_COORDINATES
        assert (collection["driftmap:site"], collection["driftmap:map_version"]) == ("north", 3)
        assert "crs" not in collection  # RFC 7946 removed it
        features = collection["features"]
        assert [f["type"] for f in features] == ["Feature"] * 4
        drive, _, vehicle, single = features
        assert drive["geometry"]["type"] == "LineString"
        assert drive["geometry"]["coordinates"] == [[p.x_m, p.y_m] for p in POSES[:3]]
        assert drive["properties"] == {
            "drive": "map-01",
            "t_s": [0.0, 0.1, 0.2],
            "yaw_rad": [0.3, 2.9, -3.1],
            "frame": [0, 1, 2],
        }
        assert vehicle["properties"]["vehicle"] == "lhd-1" and vehicle["properties"]["yaw_rad"] == [0.5, None]
        assert "frame" not in vehicle["properties"]
        assert single["geometry"] == {"type": "Point", "coordinates": [-5.0, 1.0]}

    def test_shapely_reads_the_geometries_back(self) -> None:
        tracks = tracks_from_poses(POSES) + tracks_from_positions(POSITIONS)
        features = json.loads(geojson_text(tracks))["features"]
        shapes = [shapely.geometry.shape(f["geometry"]) for f in features]
        assert all(s.is_valid for s in shapes)
        assert [s.geom_type for s in shapes] == ["LineString", "LineString", "LineString", "Point"]
        for track, read in zip(tracks, shapes, strict=True):
            expected = np.array([[p.x_m, p.y_m] for p in track.poses])
            np.testing.assert_array_equal(np.asarray(read.coords), expected)

    def test_empty_tracks_are_left_out(self) -> None:
        empty = Track("nothing", "vehicle", ())
        assert json.loads(geojson_text([empty]))["features"] == []


class TestKml:
    def test_fastkml_reads_it_back(self) -> None:
        tracks = tracks_from_poses(POSES) + tracks_from_positions(POSITIONS)
        document = kml.KML.from_string(
            kml_text(tracks, "north <map> v3", {"site": "north"}).encode()
        ).features[0]
        assert isinstance(document, kml.Document) and document.name == "north <map> v3"
        assert document.extended_data is not None
        meta = {d.name: d.value for d in document.extended_data.elements}
        assert meta == {COORDINATES_MEMBER: PLANE_COORDINATES, "driftmap:site": "north"}
        marks = document.features
        assert all(isinstance(m, kml.Placemark) for m in marks)
        assert [m.name for m in marks] == ["map-01", "map 02", "lhd-1", "truck, 2"]
        first, lhd, truck = marks[0].geometry, marks[2], marks[3].geometry
        assert isinstance(first, LineString) and isinstance(truck, Point)
        assert list(first.coords) == [(p.x_m, p.y_m, 0.0) for p in POSES[:3]]
        assert lhd.extended_data is not None
        facts = {d.name: d.value for d in lhd.extended_data.elements}
        assert facts == {"kind": "vehicle", "poses": "2", "t_start_s": "100.0", "t_end_s": "100.5"}


class TestRefusals:
    @pytest.mark.parametrize("writer", [tum_text, kitti_text])
    def test_non_finite_positions_are_refused(self, writer: object) -> None:
        track = Track("d", "drive", (TrackPose(0.0, math.nan, 0.0, 0.0),))
        with pytest.raises(ValueError, match="finite"):
            writer(track)  # type: ignore[operator]
