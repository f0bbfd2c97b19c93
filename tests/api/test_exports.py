"""Export downloads on the built tiny site: bodies read back, media types, file names, 422 naming the field,
404s and the role rule (any logged-in user; no vehicle tokens)."""

from __future__ import annotations

import io
import json
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

import ezdxf
import pytest
from evo.tools import file_interface

from driftmap.config import Settings
from driftmap.formats.csv_exports import parse_poses_csv
from driftmap.formats.g2o import parse_g2o
from driftmap.formats.position_exports import parse_positions_csv
from tests.api.access_helpers import Actors, built_tiny_data, copy_data_to_new_database, make_actors
from tests.export_site import LOADER, TRACKS, TRUCK, add_positions

MEDIA = {
    "csv": "text/csv; charset=utf-8",
    "geojson": "application/geo+json",
    "dxf": "image/vnd.dxf",
    "kml": "application/vnd.google-earth.kml+xml",
    "g2o": "text/plain; charset=utf-8",
}


@pytest.fixture(scope="module")
def actors(tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path) -> Iterator[Actors]:
    """Users of every role on a copy of the built tiny site whose vehicles have position history."""
    data, url = copy_data_to_new_database(
        built_tiny_data(tmp_path_factory.getbasetemp(), tiny_site_dir),
        tmp_path_factory.mktemp("exports") / "data",
    )
    made = make_actors(Settings(data_dir=data, database_url=url), site_name="tiny")
    add_positions(made.app.state.storage)
    with made.client:
        yield made


def _site_id(actors: Actors) -> int:
    sites = actors.client.get("/api/sites", headers=actors.auth("viewer")).json()["items"]
    return int(next(s["id"] for s in sites if s["name"] == "tiny"))


class TestMapDownloads:
    @pytest.mark.parametrize("fmt", sorted(MEDIA))
    def test_every_format_downloads_with_its_type_and_name(self, actors: Actors, fmt: str) -> None:
        site = _site_id(actors)
        response = actors.client.get(
            f"/api/sites/{site}/maps/1/export", params={"format": fmt}, headers=actors.auth("viewer")
        )
        assert response.status_code == 200, response.text
        assert response.headers["content-type"] == MEDIA[fmt]
        ext = "geojson" if fmt == "geojson" else fmt
        name = f"tiny-map-v1.{ext}"
        assert (
            response.headers["content-disposition"]
            == f"attachment; filename=\"{name}\"; filename*=UTF-8''{name}"
        )
        if fmt == "csv":
            assert len(parse_poses_csv(response.text, name)) > 0
        elif fmt == "geojson":
            assert json.loads(response.text)["type"] == "FeatureCollection"
        elif fmt == "kml":
            assert ET.fromstring(response.content).tag.endswith("kml")
        elif fmt == "dxf":
            layers = {e.dxf.layer for e in ezdxf.read(io.StringIO(response.text)).modelspace()}
            assert layers == {"DRIVE-map-01", "DRIVE-map-02"}
        else:
            assert parse_g2o(response.text).wTi.shape[0] > 0

    def test_dxf_layers_and_one_drive_as_tum_and_kitti(self, actors: Actors, tmp_path: Path) -> None:
        site = _site_id(actors)
        url = f"/api/sites/{site}/maps/1/export"
        headers = actors.auth("surveyor")
        dxf = actors.client.get(
            url, params={"format": "dxf", "nodes": True, "closures": True}, headers=headers
        )
        layers = {e.dxf.layer for e in ezdxf.read(io.StringIO(dxf.text)).modelspace()}
        assert {"NODES", "DRIVE-map-01"} <= layers
        csv = parse_poses_csv(actors.client.get(url, params={"format": "csv"}, headers=headers).text, "p.csv")
        tum = actors.client.get(url, params={"format": "tum", "drive": "map-01"}, headers=headers)
        assert tum.status_code == 200 and tum.headers["content-type"] == "text/plain; charset=utf-8"
        assert "tiny-map-v1-map-01.tum.txt" in tum.headers["content-disposition"]
        (tmp_path / "t.txt").write_text(tum.text, encoding="utf-8")
        trajectory = file_interface.read_tum_trajectory_file(str(tmp_path / "t.txt"))
        assert list(trajectory.timestamps) == [r.t_s for r in csv if r.drive == "map-01"]
        kitti = actors.client.get(url, params={"format": "kitti", "drive": "map-02"}, headers=headers)
        (tmp_path / "k.txt").write_text(kitti.text, encoding="utf-8")
        assert file_interface.read_kitti_poses_file(str(tmp_path / "k.txt")).num_poses == sum(
            r.drive == "map-02" for r in csv
        )

    def test_bad_format_several_drives_and_unknown_things(self, actors: Actors) -> None:
        site = _site_id(actors)
        url = f"/api/sites/{site}/maps/1/export"
        bad = actors.client.get(url, params={"format": "shp"}, headers=actors.auth("viewer"))
        assert bad.status_code == 422 and bad.json()["errors"][0]["loc"] == ["query", "format"]
        missing = actors.client.get(url, headers=actors.auth("viewer"))
        assert missing.status_code == 422 and missing.json()["errors"][0]["loc"] == ["query", "format"]
        several = actors.client.get(url, params={"format": "tum"}, headers=actors.auth("viewer"))
        assert several.status_code == 422 and several.json()["field"] == "drive"
        for path, params in (
            ("/api/sites/999999/maps/1/export", {"format": "csv"}),
            (f"/api/sites/{site}/maps/9/export", {"format": "csv"}),
            (url, {"format": "csv", "drive": "nope"}),
        ):
            response = actors.client.get(path, params=params, headers=actors.auth("viewer"))
            assert response.status_code == 404, (path, response.text)

    def test_only_users_may_download(self, actors: Actors) -> None:
        url = f"/api/sites/{_site_id(actors)}/maps/1/export"
        assert actors.client.get(url, params={"format": "csv"}).status_code == 401
        vehicle = actors.client.get(url, params={"format": "csv"}, headers=actors.auth("vehicle"))
        assert vehicle.status_code == 403


class TestPositionDownloads:
    def test_csv_of_one_vehicle_over_a_range(self, actors: Actors) -> None:
        url = f"/api/sites/{_site_id(actors)}/positions/export"
        response = actors.client.get(
            url,
            params={"format": "csv", "vehicle": LOADER, "since": 101, "until": 103},
            headers=actors.auth("viewer"),
        )
        assert response.status_code == 200, response.text
        assert response.headers["content-type"] == MEDIA["csv"]
        assert f'filename="tiny-positions-{LOADER}.csv"' in response.headers["content-disposition"]
        rows = parse_positions_csv(response.text, "p.csv")
        assert [(r.vehicle, r.t_s, r.x_m) for r in rows] == [
            (LOADER, 101.0, 6.0),
            (LOADER, 102.0, 7.0),
            (LOADER, 103.0, 8.0),
        ]

    def test_every_vehicle_as_geojson_kml_and_one_as_tum(self, actors: Actors, tmp_path: Path) -> None:
        url = f"/api/sites/{_site_id(actors)}/positions/export"
        geojson = actors.client.get(url, params={"format": "geojson"}, headers=actors.auth("admin"))
        assert geojson.headers["content-type"] == MEDIA["geojson"]
        features = json.loads(geojson.text)["features"]
        assert [f["properties"]["vehicle"] for f in features] == [LOADER, TRUCK]  # lhd-1, lhd-2 have none
        kml = actors.client.get(url, params={"format": "kml"}, headers=actors.auth("admin"))
        assert ET.fromstring(kml.content).tag.endswith("kml")
        tum = actors.client.get(url, params={"format": "tum", "vehicle": TRUCK}, headers=actors.auth("admin"))
        assert "filename*=UTF-8''tiny-positions-truck%202.tum.txt" in tum.headers["content-disposition"]
        (tmp_path / "t.txt").write_text(tum.text, encoding="utf-8")
        assert (
            list(file_interface.read_tum_trajectory_file(str(tmp_path / "t.txt")).timestamps) == TRACKS[1].t
        )

    def test_bad_range_format_and_unknown_vehicle(self, actors: Actors) -> None:
        site = _site_id(actors)
        url = f"/api/sites/{site}/positions/export"
        viewer = actors.auth("viewer")
        backwards = actors.client.get(url, params={"format": "csv", "since": 5, "until": 4}, headers=viewer)
        assert backwards.status_code == 422 and backwards.json()["field"] == "until"
        not_a_number = actors.client.get(url, params={"format": "csv", "since": "soon"}, headers=viewer)
        assert not_a_number.status_code == 422 and not_a_number.json()["errors"][0]["loc"] == [
            "query",
            "since",
        ]
        g2o = actors.client.get(url, params={"format": "g2o"}, headers=viewer)
        assert g2o.status_code == 422 and g2o.json()["errors"][0]["loc"] == ["query", "format"]
        ghost = actors.client.get(url, params={"format": "csv", "vehicle": "ghost"}, headers=viewer)
        assert ghost.status_code == 404
        assert (
            actors.client.get(
                "/api/sites/999999/positions/export", params={"format": "csv"}, headers=viewer
            ).status_code
            == 404
        )
        assert actors.client.get(url, params={"format": "csv"}).status_code == 401
        assert (
            actors.client.get(url, params={"format": "csv"}, headers=actors.auth("vehicle")).status_code
            == 403
        )
