"""A site's coordinates through the API: set by a surveyor, shown with the site, used by the GeoJSON and KML
exports (WGS84 with an EPSG code), refused naming the field with nothing changed, cleared."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from driftmap.config import Settings
from driftmap.formats.site_crs import SiteCrs
from tests.api.access_helpers import Actors, built_tiny_data, copy_data_to_new_database, make_actors

MGA_55 = {"epsg": 28355, "false_easting_m": 321_000.0, "false_northing_m": 6_123_000.0, "rotation_deg": 3.0}


@pytest.fixture
def actors(tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path, tmp_path: Path) -> Iterator[Actors]:
    data, url = copy_data_to_new_database(
        built_tiny_data(tmp_path_factory.getbasetemp(), tiny_site_dir), tmp_path / "data"
    )
    made = make_actors(Settings(data_dir=data, database_url=url), site_name="tiny")
    with made.client:
        yield made


def _site(actors: Actors) -> dict:
    sites = actors.client.get("/api/sites", headers=actors.auth("viewer")).json()["items"]
    return next(s for s in sites if s["name"] == "tiny")


def _export(actors: Actors, site: int, fmt: str) -> str:
    r = actors.client.get(
        f"/api/sites/{site}/maps/1/export", params={"format": fmt}, headers=actors.auth("viewer")
    )
    assert r.status_code == 200, r.text
    return r.text


def test_a_surveyor_places_the_site_and_exports_follow(actors: Actors) -> None:
    site = _site(actors)["id"]
    plane = json.loads(_export(actors, site, "geojson"))
    assert plane["driftmap:coordinates"] == "site plane metres"
    r = actors.client.put(f"/api/sites/{site}/crs", json=MGA_55, headers=actors.auth("surveyor"))
    assert r.status_code == 200, r.text
    assert r.json()["crs"] == MGA_55 | {"scale": 1.0, "proj4": SiteCrs(28355).proj4()}
    assert "+proj=utm +zone=55 +south" in r.json()["crs"]["proj4"]
    assert _site(actors)["crs"]["epsg"] == 28355

    placed = json.loads(_export(actors, site, "geojson"))
    assert "EPSG:28355" in placed["driftmap:coordinates"]
    crs = SiteCrs(**MGA_55)  # type: ignore[arg-type]
    for before, after in zip(plane["features"], placed["features"], strict=True):
        xy = np.array(before["geometry"]["coordinates"])
        lonlat = np.array(after["geometry"]["coordinates"])
        assert lonlat[:, 0] == pytest.approx(145.0, abs=1.0) and lonlat[:, 1] == pytest.approx(-35.0, abs=1.0)
        np.testing.assert_allclose(crs.from_wgs84(lonlat), xy, atol=1e-3)  # the same floor points
    kml = ET.fromstring(_export(actors, site, "kml"))
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    first = kml.find(".//k:Placemark//k:coordinates", ns)
    assert first is not None and first.text is not None
    lon, lat, _z = (float(v) for v in first.text.split()[0].split(","))
    assert 144.0 < lon < 146.0 and -36.0 < lat < -34.0
    assert _export(actors, site, "csv").splitlines()[0] == "drive,frame,t,x,y,yaw"  # CSV stays in the plane

    r = actors.client.put(f"/api/sites/{site}/crs", json={}, headers=actors.auth("surveyor"))
    assert r.status_code == 200 and r.json()["crs"] is None
    assert json.loads(_export(actors, site, "geojson"))["driftmap:coordinates"] == "site plane metres"


@pytest.mark.parametrize(
    ("body", "field"),
    [
        ({"epsg": 4326}, "crs.epsg"),
        ({"epsg": 999_998}, "crs.epsg"),
        ({"scale": 0}, "scale"),
        ({"zone": 1}, "zone"),
    ],
)
def test_bad_coordinates_are_refused_naming_the_field(actors: Actors, body: dict, field: str) -> None:
    site = _site(actors)["id"]
    assert (
        actors.client.put(f"/api/sites/{site}/crs", json=MGA_55, headers=actors.auth("admin")).status_code
        == 200
    )
    r = actors.client.put(f"/api/sites/{site}/crs", json=body, headers=actors.auth("surveyor"))
    assert r.status_code == 422, r.text
    assert field in r.text
    assert _site(actors)["crs"]["epsg"] == 28355  # unchanged


def test_viewers_cannot_place_a_site(actors: Actors) -> None:
    site = _site(actors)["id"]
    r = actors.client.put(f"/api/sites/{site}/crs", json=MGA_55, headers=actors.auth("viewer"))
    assert r.status_code == 403
    assert _site(actors)["crs"] is None
