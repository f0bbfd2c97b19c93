"""Exports of the built tiny map and of stored vehicle positions, on the run's real database: every format
written by the service, read back by its reader and compared with the stored rows."""

from __future__ import annotations

import io
import json
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

import ezdxf
import gtsam
import numpy as np
import pytest
from evo.tools import file_interface
from sqlalchemy import func, select

from driftmap.errors import BadInputError, NotFoundError
from driftmap.formats.csv_exports import parse_poses_csv
from driftmap.formats.drive_folder import read_drive_folder
from driftmap.formats.g2o import parse_g2o, relative_poses
from driftmap.formats.position_exports import parse_positions_csv
from driftmap.formats.trajectory_exports import COORDINATES_MEMBER, KML_NAMESPACE, PLANE_COORDINATES
from driftmap.services import exports as export_service
from driftmap.services import map_views
from driftmap.services import maps as map_service
from driftmap.services import sites as site_service
from driftmap.store.models import MapGroundingResidual, MapLoopClosure, MapVersion, Site
from driftmap.store.storage import Storage
from tests.export_site import LOADER, SITE, TRACKS, TRUCK, export_store
from tests.formats.test_g2o import assert_read_by_gtsam

DRIVES = ("map-01", "map-02")  # the tiny site's mapping drives


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path) -> Iterator[Storage]:
    opened = Storage.open(export_store(tmp_path_factory, tiny_site_dir))
    yield opened
    opened.close()


def _map(store: Storage, fmt: str, **options: object) -> export_service.ExportFile:
    with store.db.session() as session:
        site = site_service.get_site(session, SITE)
        version = map_service.get_map_version(session, site, 1)
        return export_service.export_map(session, store.blobs, site, version, fmt, **options)  # type: ignore[arg-type]


def _positions(store: Storage, fmt: str, **options: object) -> export_service.ExportFile:
    with store.db.session() as session:
        site = site_service.get_site(session, SITE)
        return export_service.export_positions(session, site, fmt, **options)  # type: ignore[arg-type]


def _site_and_version(store: Storage) -> tuple[Site, MapVersion]:
    with store.db.session() as session:
        site = site_service.get_site(session, SITE)
        return site, map_service.get_map_version(session, site, 1)


class TestMapExports:
    def test_csv_holds_every_pose_with_its_frame_time(self, store: Storage, tiny_site_dir: Path) -> None:
        exported = _map(store, "csv")
        assert (exported.media_type, exported.filename) == ("text/csv", "tiny-map-v1.csv")
        rows = parse_poses_csv(exported.text, exported.filename)
        with store.db.session() as session:
            stored = map_service.pose_rows(
                session, map_service.get_map_version(session, site_service.get_site(session, SITE), 1)
            )
        assert [(r.drive, r.frame, r.x_m, r.y_m, r.yaw_rad) for r in rows] == [
            (r.drive, r.frame, r.x_m, r.y_m, r.yaw_rad) for r in stored
        ]
        times = {
            (d, f.frame): f.t_s
            for d in DRIVES
            for f in read_drive_folder(tiny_site_dir / "drives" / d).frames
        }
        assert [r.t_s for r in rows] == [times[(r.drive, r.frame)] for r in rows]
        assert exported.records == len(rows) == len(times)

    def test_geojson_has_a_line_per_drive_in_plane_metres(self, store: Storage) -> None:
        rows = parse_poses_csv(_map(store, "csv").text, "poses.csv")
        exported = _map(store, "geojson")
        assert exported.media_type == "application/geo+json"
        collection = json.loads(exported.text)
        assert collection[COORDINATES_MEMBER] == PLANE_COORDINATES and collection["driftmap:map_version"] == 1
        features = collection["features"]
        assert [f["properties"]["drive"] for f in features] == list(DRIVES)
        for feature in features:
            mine = [r for r in rows if r.drive == feature["properties"]["drive"]]
            assert feature["geometry"]["type"] == "LineString"
            assert feature["geometry"]["coordinates"] == [[r.x_m, r.y_m] for r in mine]
            assert feature["properties"]["t_s"] == [r.t_s for r in mine]
            assert feature["properties"]["frame"] == [r.frame for r in mine]

    def test_kml_has_a_placemark_per_drive(self, store: Storage) -> None:
        rows = parse_poses_csv(_map(store, "csv").text, "poses.csv")
        root = ET.fromstring(_map(store, "kml").text)
        ns = {"k": KML_NAMESPACE}
        marks = root.findall("k:Document/k:Placemark", ns)
        assert [m.findtext("k:name", namespaces=ns) for m in marks] == list(DRIVES)
        text = marks[1].findtext("k:LineString/k:coordinates", namespaces=ns) or ""
        assert [[float(v) for v in p.split(",")[:2]] for p in text.split()] == [
            [r.x_m, r.y_m] for r in rows if r.drive == DRIVES[1]
        ]

    def test_dxf_layers_per_drive_with_nodes_and_closures(self, store: Storage) -> None:
        rows = parse_poses_csv(_map(store, "csv").text, "poses.csv")
        plain = ezdxf.read(io.StringIO(_map(store, "dxf").text))
        assert {e.dxf.layer for e in plain.modelspace()} == {f"DRIVE-{d}" for d in DRIVES}
        exported = _map(store, "dxf", nodes=True, closures=True)
        assert (exported.media_type, exported.filename) == ("image/vnd.dxf", "tiny-map-v1.dxf")
        msp = ezdxf.read(io.StringIO(exported.text)).modelspace()
        line = msp.query('LWPOLYLINE[layer=="DRIVE-map-02"]')[0]
        assert [tuple(p) for p in line.get_points("xy")] == [
            (r.x_m, r.y_m) for r in rows if r.drive == "map-02"
        ]
        _site, version = _site_and_version(store)
        with store.db.session() as session:
            counts = map_views.version_counts(session, version)
        assert len(msp.query('POINT[layer=="NODES"]')) == counts["nodes"] > 0
        kept, rejected = (
            len(msp.query(f'LINE[layer=="{layer}"]')) for layer in ("CLOSURES", "CLOSURES-REJECTED")
        )
        assert (kept, kept + rejected) == (counts["closures_accepted"], counts["closures"])

    def test_tum_and_kitti_hold_one_drive(self, store: Storage, tmp_path: Path) -> None:
        with pytest.raises(BadInputError) as caught:
            _map(store, "tum")
        assert caught.value.field == "drive" and "'map-01', 'map-02'" in str(caught.value)
        rows = [r for r in parse_poses_csv(_map(store, "csv").text, "p.csv") if r.drive == "map-02"]
        tum = _map(store, "tum", drive="map-02")
        assert tum.filename == "tiny-map-v1-map-02.tum.txt" and tum.records == len(rows)
        (tmp_path / "t.txt").write_text(tum.text, encoding="utf-8")
        trajectory = file_interface.read_tum_trajectory_file(str(tmp_path / "t.txt"))
        np.testing.assert_array_equal(trajectory.timestamps, [r.t_s for r in rows])
        np.testing.assert_array_equal(trajectory.positions_xyz, [[r.x_m, r.y_m, 0.0] for r in rows])
        (tmp_path / "k.txt").write_text(_map(store, "kitti", drive="map-02").text, encoding="utf-8")
        path = file_interface.read_kitti_poses_file(str(tmp_path / "k.txt"))
        np.testing.assert_array_equal(path.positions_xyz, [[r.x_m, r.y_m, 0.0] for r in rows])
        yaw = np.arctan2([m[1, 0] for m in path.poses_se3], [m[0, 0] for m in path.poses_se3])
        np.testing.assert_allclose(np.cos(yaw - [r.yaw_rad for r in rows]), 1.0, atol=1e-12)

    def test_g2o_is_the_pose_graph_at_its_solution(self, store: Storage, tmp_path: Path) -> None:
        rows = parse_poses_csv(_map(store, "csv").text, "p.csv")
        exported = _map(store, "g2o")
        graph = parse_g2o(exported.text, exported.filename)
        np.testing.assert_array_equal(graph.wTi, [[r.x_m, r.y_m, r.yaw_rad] for r in rows])
        _site, version = _site_and_version(store)
        with store.db.session() as session:
            accepted = session.scalar(
                select(func.count()).where(
                    MapLoopClosure.map_version_id == version.id, MapLoopClosure.accepted
                )
            )
            grounded = session.scalar(
                select(func.count()).where(MapGroundingResidual.map_version_id == version.id)
            )
        assert graph.edge_ij.shape[0] == len(rows) - len(DRIVES) + accepted
        assert graph.fixed.size == grounded > 0
        np.testing.assert_allclose(graph.iTj, relative_poses(graph.wTi, graph.edge_ij), atol=1e-9)
        odometry = graph.edge_ij[: len(rows) - len(DRIVES)]
        assert np.all(odometry[:, 1] == odometry[:, 0] + 1)
        path = tmp_path / exported.filename
        path.write_text(exported.text)
        assert_read_by_gtsam(graph, *gtsam.readG2o(str(path), False))

    def test_one_drive_keeps_its_own_edges_and_closures(self, store: Storage) -> None:
        rows = [r for r in parse_poses_csv(_map(store, "csv").text, "p.csv") if r.drive == "map-01"]
        graph = parse_g2o(_map(store, "g2o", drive="map-01").text)
        np.testing.assert_array_equal(graph.wTi, [[r.x_m, r.y_m, r.yaw_rad] for r in rows])
        assert graph.edge_ij.shape[0] >= len(rows) - 1 and graph.edge_ij.max() < len(rows)
        msp = ezdxf.read(io.StringIO(_map(store, "dxf", drive="map-01", closures=True).text)).modelspace()
        assert {e.dxf.layer for e in msp.query("LWPOLYLINE")} == {"DRIVE-map-01"}

    def test_refusals(self, store: Storage) -> None:
        with pytest.raises(BadInputError) as caught:
            _map(store, "shp")
        assert caught.value.field == "format"
        with pytest.raises(NotFoundError, match="no drive named 'nope'"):
            _map(store, "csv", drive="nope")


class TestPositionExports:
    def test_csv_of_every_vehicle_in_time_order(self, store: Storage) -> None:
        exported = _positions(store, "csv")
        assert exported.filename == "tiny-positions.csv"
        rows = parse_positions_csv(exported.text, exported.filename)
        by_name = {t.vehicle: t for t in TRACKS}
        assert [r.vehicle for r in rows] == [LOADER] * 10 + [TRUCK] * 3
        for name in (LOADER, TRUCK):
            mine = [r for r in rows if r.vehicle == name]
            track = by_name[name]
            assert [(r.t_s, r.x_m, r.y_m, r.yaw_rad) for r in mine] == list(
                zip(track.t, track.x, track.y, track.yaw, strict=True)
            )
        assert all(r.confidence == 0.75 and r.matched and not r.lost for r in rows)

    def test_one_vehicle_over_a_range(self, store: Storage) -> None:
        exported = _positions(store, "csv", vehicle=LOADER, since_s=102.0, until_s=104.5)
        assert exported.filename == f"tiny-positions-{LOADER}.csv"
        rows = parse_positions_csv(exported.text, "p.csv")
        assert [r.t_s for r in rows] == [102.0, 103.0, 104.0]
        assert _positions(store, "csv", since_s=1000.0).records == 0

    def test_tum_geojson_and_kml(self, store: Storage, tmp_path: Path) -> None:
        with pytest.raises(BadInputError) as caught:
            _positions(store, "tum")
        assert caught.value.field == "vehicle"
        (tmp_path / "t.txt").write_text(_positions(store, "tum", vehicle=TRUCK).text, encoding="utf-8")
        trajectory = file_interface.read_tum_trajectory_file(str(tmp_path / "t.txt"))
        np.testing.assert_array_equal(trajectory.timestamps, TRACKS[1].t)
        collection = json.loads(_positions(store, "geojson", until_s=101.0).text)
        assert collection["driftmap:until_s"] == 101.0 and "driftmap:since_s" not in collection
        assert [f["properties"]["vehicle"] for f in collection["features"]] == [LOADER, TRUCK]
        assert collection["features"][0]["geometry"]["coordinates"] == [[5.0, 2.5], [6.0, 2.5]]
        root = ET.fromstring(_positions(store, "kml", vehicle=LOADER).text)
        names = [e.text for e in root.iter(f"{{{KML_NAMESPACE}}}name")]
        assert names == ["tiny vehicle positions", LOADER]

    def test_dxf_and_kitti(self, store: Storage, tmp_path: Path) -> None:
        exported = _positions(store, "dxf")
        assert exported.filename == "tiny-positions.dxf"
        msp = ezdxf.read(io.StringIO(exported.text)).modelspace()
        for track in TRACKS:  # a layer per vehicle holding its track, site plane metres
            (line,) = msp.query(f'LWPOLYLINE[layer=="VEHICLE-{track.vehicle}"]')
            np.testing.assert_allclose(np.array(line.get_points("xy")), np.c_[track.x, track.y])
        with pytest.raises(BadInputError) as caught:
            _positions(store, "kitti")
        assert caught.value.field == "vehicle"
        (tmp_path / "k.txt").write_text(_positions(store, "kitti", vehicle=LOADER).text, encoding="utf-8")
        poses = file_interface.read_kitti_poses_file(str(tmp_path / "k.txt"))
        np.testing.assert_allclose(poses.positions_xyz[:, :2], np.c_[TRACKS[0].x, TRACKS[0].y], atol=1e-9)

    def test_refusals(self, store: Storage) -> None:
        with pytest.raises(BadInputError) as caught:
            _positions(store, "csv", since_s=5.0, until_s=4.0)
        assert caught.value.field == "until"
        with pytest.raises(BadInputError) as caught:
            _positions(store, "g2o")
        assert caught.value.field == "format"
        with pytest.raises(BadInputError) as caught:
            _positions(store, "csv", since_s=float("nan"))
        assert caught.value.field == "since"
        with pytest.raises(NotFoundError, match="no vehicle named 'ghost'"):
            _positions(store, "csv", vehicle="ghost")
