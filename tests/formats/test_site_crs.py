"""A site's coordinates: the mine-grid transform and an EPSG code, against published projection parameters."""

from __future__ import annotations

import math

import numpy as np
import pytest

from driftmap.errors import BadInputError
from driftmap.formats.site_crs import SiteCrs
from driftmap.formats.trajectory_exports import PLANE_COORDINATES

UTM_33N = 32633  # WGS 84 / UTM zone 33N: central meridian 15 E, false easting 500 km, false northing 0
MGA_55 = 28355  # GDA94 / MGA zone 55: central meridian 147 E, false easting 500 km, false northing 10,000 km


class TestControlPoints:
    def test_a_central_meridian_on_the_equator(self) -> None:
        for epsg, false_north, lon in ((UTM_33N, 0.0, 15.0), (MGA_55, 10_000_000.0, 147.0)):
            crs = SiteCrs(epsg, false_easting_m=500_000.0, false_northing_m=false_north)
            lonlat = crs.to_wgs84(np.array([[0.0, 0.0]]))
            assert lonlat[0] == pytest.approx([lon, 0.0], abs=1e-9)

    def test_a_kilometre_north_on_the_central_meridian(self) -> None:
        # the UTM scale factor on the central meridian is 0.9996: a grid kilometre is 1000/0.9996 m of meridian
        crs = SiteCrs(UTM_33N, false_easting_m=500_000.0)
        lon, lat = crs.to_wgs84(np.array([[0.0, 1000.0]]))[0]
        assert lon == pytest.approx(15.0, abs=1e-12)
        metres_per_degree = 110_574.3  # meridian arc per degree of latitude at the equator (WGS84)
        assert lat * metres_per_degree == pytest.approx(1000.0 / 0.9996, rel=1e-4)

    def test_round_trips_within_a_millimetre(self) -> None:
        crs = SiteCrs(MGA_55, 321_456.7, 6_123_456.7, rotation_deg=12.5, scale=1.0003)
        plane = np.random.default_rng(0).uniform(-3000.0, 3000.0, (50, 2))
        back = crs.from_wgs84(crs.to_wgs84(plane))
        assert np.abs(back - plane).max() < 1e-3
        assert np.abs(crs.from_grid(crs.to_grid(plane)) - plane).max() < 1e-9


class TestMineGrid:
    def test_rotation_scale_and_false_origin(self) -> None:
        crs = SiteCrs(false_easting_m=1000.0, false_northing_m=2000.0, rotation_deg=90.0, scale=1.5)
        grid = crs.to_grid(np.array([[10.0, 0.0], [0.0, 10.0]]))
        np.testing.assert_allclose(grid, [[1000.0, 2015.0], [985.0, 2000.0]], atol=1e-9)

    def test_labels_say_what_exports_hold(self) -> None:
        assert SiteCrs().export_label() == PLANE_COORDINATES and SiteCrs().is_plane
        assert "mine grid" in SiteCrs(false_easting_m=5.0).export_label()
        assert "EPSG:32633" in SiteCrs(UTM_33N).export_label()
        with pytest.raises(BadInputError, match="no EPSG code"):
            SiteCrs(false_easting_m=5.0).to_wgs84(np.zeros((1, 2)))


class TestRefusals:
    @pytest.mark.parametrize(
        ("kwargs", "field"),
        [
            ({"epsg": 4326}, "crs.epsg"),  # geographic: degrees, not a grid
            ({"epsg": 999_999}, "crs.epsg"),  # no such code
            ({"epsg": 12}, "crs.epsg"),
            ({"scale": 0.0}, "crs.scale"),
            ({"false_easting_m": math.nan}, "crs.false_easting_m"),
            ({"rotation_deg": math.inf}, "crs.rotation_deg"),
        ],
    )
    def test_bad_values_name_their_field(self, kwargs: dict[str, float], field: str) -> None:
        with pytest.raises(BadInputError) as caught:
            SiteCrs(**kwargs)  # type: ignore[arg-type]
        assert caught.value.field == field

    def test_unknown_keys_are_named(self) -> None:
        with pytest.raises(BadInputError) as caught:
            SiteCrs.from_json({"epsg": UTM_33N, "zone": 33})
        assert caught.value.field == "crs.zone"
