"""The site's coordinates in the browser: a surveyor places the plan on the mine grid and the Earth through the
form beside the survey map, the pointer's readout then shows the grid and longitude/latitude (proj4js in the
browser, checked against pyproj), and so do the selected vehicle's details; a refused EPSG code is explained next
to its field and changes nothing; a viewer reads the values without a form. Against a real ``driftmap serve``
(fixtures of ``conftest.py``).

Every wait polls the DOM or the API up to a deadline (Playwright's ``expect``); nothing sleeps for a fixed time.
"""

from __future__ import annotations

import re
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from playwright.sync_api import Page, expect

from driftmap.formats.site_crs import SiteCrs
from tests.api.access_helpers import localisation_drive, recorded_frames
from tests.e2e.conftest import PageWithLog, Server, screenshot
from tests.e2e.map_helpers import readout_at
from tests.e2e.test_monitoring import Vehicle
from tests.e2e.test_ui import log_in, make_user

pytestmark = pytest.mark.slow  # a real server and a browser

EPSG = 28355  # GDA94 / MGA zone 55 (south-east Australia)
FALSE_EASTING_M, FALSE_NORTHING_M = 321_000.0, 6_123_000.0  # about 145.04 E, 35.02 S
DEGREES_TOL = 1e-5  # proj4js against pyproj, and the readout's plane metres rounded to 2 decimals (~1 m)


def site_crs(server: Server) -> dict[str, Any] | None:
    answer = server.api("GET", "/api/sites/1")
    assert answer.status_code == 200, answer.text
    crs: dict[str, Any] | None = answer.json()["crs"]
    return crs


def wgs84(x: float, y: float) -> tuple[float, float]:
    """pyproj's longitude, latitude of a plane point with the surveyor's coordinates."""
    crs = SiteCrs(epsg=EPSG, false_easting_m=FALSE_EASTING_M, false_northing_m=FALSE_NORTHING_M)
    lon, lat = crs.to_wgs84(np.array([[x, y]]))[0]
    return float(lon), float(lat)


def open_survey(p: Page, server: Server, name: str, role: str) -> None:
    log_in(p, server, name, make_user(server, name, role))
    p.get_by_test_id("nav-survey").click()
    expect(p.get_by_test_id("map")).to_have_attribute("data-ready", "yes")


class TestSiteCoordinates:
    def test_a_surveyor_places_the_site_and_the_readout_shows_longitude_latitude(
        self, server: Server, page: PageWithLog
    ) -> None:
        p = page.page
        open_survey(p, server, "crs-surveyor", "surveyor")
        form = p.get_by_test_id("crs-form")
        form.get_by_test_id("crs-epsg").fill(str(EPSG))
        form.get_by_test_id("crs-false_easting_m").fill(f"{FALSE_EASTING_M:.0f}")
        form.get_by_test_id("crs-false_northing_m").fill(f"{FALSE_NORTHING_M:.0f}")
        form.get_by_test_id("crs-save").click()
        expect(form.get_by_test_id("crs-status")).to_have_text("Saved.")

        crs = site_crs(server)
        assert crs is not None
        assert crs["epsg"] == EPSG
        assert (crs["false_easting_m"], crs["false_northing_m"]) == (FALSE_EASTING_M, FALSE_NORTHING_M)
        assert (crs["rotation_deg"], crs["scale"]) == (0.0, 1.0)
        expect(form.get_by_test_id("crs-proj4")).to_contain_text("+zone=55")

        box = p.get_by_test_id("map").bounding_box()
        assert box is not None
        x, y = readout_at(p, box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        readout = p.get_by_test_id("grid-readout")
        expect(readout).to_contain_text("plan E ")
        lonlat = readout.get_by_test_id("pointer-lonlat")
        expect(lonlat).to_have_text(re.compile(r"^14[45]\.\d{6}° E\s+3[45]\.\d{6}° S$"))
        lon, lat = (
            float(lonlat.get_attribute("data-lon") or "nan"),
            float(lonlat.get_attribute("data-lat") or "nan"),
        )
        want = wgs84(x, y)
        assert abs(lon - want[0]) < DEGREES_TOL and abs(lat - want[1]) < DEGREES_TOL, (lon, lat, want)
        assert 144.5 < lon < 145.5 and -35.5 < lat < -34.5, (lon, lat)
        grid = readout.get_by_test_id("pointer-grid")
        expect(grid).to_have_text(f"grid E {FALSE_EASTING_M + x:.2f}  N {FALSE_NORTHING_M + y:.2f}")
        screenshot(p, "ui_site_coordinates")
        assert page.errors == []

    def test_an_unprojected_epsg_code_is_explained_and_changes_nothing(
        self, server: Server, page: PageWithLog
    ) -> None:
        before = site_crs(server)
        p = page.page
        open_survey(p, server, "crs-surveyor-2", "surveyor")
        form = p.get_by_test_id("crs-form")
        form.get_by_test_id("crs-epsg").fill("4326")
        form.get_by_test_id("crs-save").click()
        error = form.get_by_test_id("crs-error-epsg")
        expect(error).to_contain_text("EPSG:4326")
        expect(error).to_contain_text("not a projected system")
        expect(form.get_by_test_id("crs-status")).to_have_count(0)
        assert site_crs(server) == before
        page.errors.clear()  # the browser logs the refused request (422)

    def test_the_selected_vehicles_position_in_longitude_latitude(
        self, server: Server, page: PageWithLog, tiny_site_dir: Path
    ) -> None:
        crs = site_crs(server)
        assert crs is not None and crs["epsg"] == EPSG, "runs after the surveyor's test"
        vehicle = Vehicle(server, "crs-truck")
        frame = recorded_frames(localisation_drive(tiny_site_dir), 1)[0]
        vehicle.post(time.time(), frame.data)
        latest = server.api("GET", "/api/positions/latest", params={"site_id": 1})
        assert latest.status_code == 200, latest.text
        position = next(v["position"] for v in latest.json() if v["vehicle_id"] == vehicle.id)
        assert position is not None
        p = page.page
        open_survey(p, server, "crs-surveyor-3", "surveyor")
        p.get_by_test_id("nav-monitor").click()
        p.get_by_test_id("vehicle-row-crs-truck").click()
        lonlat = p.get_by_test_id("detail-position").get_by_test_id("vehicle-lonlat")
        expect(lonlat).to_have_text(re.compile(r"^14[45]\.\d{6}° E\s+3[45]\.\d{6}° S$"))
        lon, lat = (
            float(lonlat.get_attribute("data-lon") or "nan"),
            float(lonlat.get_attribute("data-lat") or "nan"),
        )
        want = wgs84(position["x"], position["y"])
        assert abs(lon - want[0]) < DEGREES_TOL and abs(lat - want[1]) < DEGREES_TOL, (lon, lat, want)
        assert page.errors == []

    def test_a_viewer_reads_the_values_without_a_form(self, server: Server, page: PageWithLog) -> None:
        crs = site_crs(server)
        assert crs is not None and crs["epsg"] == EPSG, "runs after the surveyor's test"
        p = page.page
        open_survey(p, server, "crs-viewer", "viewer")
        panel = p.get_by_test_id("site-coordinates")
        expect(panel.get_by_test_id("crs-value-epsg")).to_have_text(str(EPSG))
        expect(panel.get_by_test_id("crs-value-false_easting_m")).to_have_text(f"{FALSE_EASTING_M:.0f} m")
        expect(panel.get_by_test_id("crs-form")).to_have_count(0)
        assert page.errors == []
