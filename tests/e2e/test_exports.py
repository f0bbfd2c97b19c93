"""Downloads in the browser, through the buttons where the data is shown: a map version's export on the grounding
page and vehicle position history on the monitoring page (the files checked against the API's and parsed), its
range following what the view shows (the history's window, a loaded replay), a refused export explained with the
server's reason; and the vehicle list's last-seen column, with every column inside the side panel at 1366 and
1440 px wide. Against a real ``driftmap serve`` (fixtures of ``conftest.py``).

Every wait polls the DOM or the API up to a deadline (Playwright's ``expect``); nothing sleeps for a fixed time.
"""

from __future__ import annotations

import csv
import io
import json
import re
import time
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Download, Locator, Page, expect

from tests.api.access_helpers import localisation_drive, recorded_frames
from tests.e2e.conftest import VIEWPORT_H, PageWithLog, Server, screenshot
from tests.e2e.test_monitoring import Vehicle, log_in

pytestmark = pytest.mark.slow  # a real server and a browser

FRAMES = 8
FRAME_PERIOD_S = 0.1
POSITIONS_HEADER = "vehicle,t,x,y,yaw,node,confidence,matched,lost,speed"
POSES_HEADER = "drive,frame,t,x,y,yaw"
CLOCK_TEXT = re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d$")  # a wall-clock range input, local time
WIDE_VIEWPORTS = (1366, 1440)


def download_through(page: Page, button: Locator) -> tuple[str, bytes]:
    """Click ``button`` and return the file the browser saved: its name and content."""
    with page.expect_download() as info:
        button.click()
    saved: Download = info.value
    return saved.suggested_filename, Path(saved.path()).read_bytes()


@pytest.fixture(scope="module")
def fleet(server: Server, tiny_site_dir: Path) -> dict[str, Vehicle]:
    """Two vehicles on the wall clock (as ``driftmap replay`` posts), each with a minute-old history of
    ``FRAMES`` positions and no camera odometry (the list shows their appearance-only badge)."""
    frames = recorded_frames(localisation_drive(tiny_site_dir), FRAMES)
    t0 = round(time.time()) - 60.0
    fleet = {}
    for k, name in enumerate(("haul-truck-07", "lhd-2")):
        vehicle = fleet[name] = Vehicle(server, name)
        for i, frame in enumerate(frames):
            assert vehicle.post(t0 + 10.0 * k + FRAME_PERIOD_S * i, frame.data)["status"] == "processed"
    return fleet


class TestMapExport:
    def test_download_the_latest_version_as_geojson_and_csv(self, server: Server, page: PageWithLog) -> None:
        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-grounding").click()
        expect(p.get_by_test_id("map-version")).to_have_text("map v1")
        box = p.get_by_test_id("map-export")
        expect(box.get_by_test_id("map-export-version")).to_have_value("1")
        expect(box.get_by_test_id("map-export-format")).to_have_value("geojson")

        name, data = download_through(p, box.get_by_test_id("map-export-download"))
        assert name == "tiny-map-v1.geojson"
        assert data == server.api("GET", "/api/sites/1/maps/1/export", params={"format": "geojson"}).content
        collection = json.loads(data)
        poses = server.api("GET", "/api/sites/1/maps/1/poses").json()
        assert collection["type"] == "FeatureCollection"
        assert sum(len(f["properties"]["frame"]) for f in collection["features"]) == len(poses["frame"])
        expect(box.get_by_test_id("map-export-saved")).to_have_text(f"Saved {name}")

        box.get_by_test_id("map-export-format").select_option("csv")
        name, data = download_through(p, box.get_by_test_id("map-export-download"))
        assert name == "tiny-map-v1.csv"
        rows = list(csv.reader(io.StringIO(data.decode())))
        assert ",".join(rows[0]) == POSES_HEADER
        assert len(rows) - 1 == len(poses["frame"])
        screenshot(p, "ui_map_export")
        assert page.errors == []

    def test_a_refused_export_shows_the_servers_reason(self, server: Server, page: PageWithLog) -> None:
        poses = server.api("GET", "/api/sites/1/maps/1/poses").json()
        assert len(set(poses["drive_id"])) > 1, "the tiny site's map has one drive: TUM takes it"
        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-grounding").click()
        box = p.get_by_test_id("map-export")
        downloads: list[Download] = []
        p.on("download", lambda d: downloads.append(d))
        # TUM holds one drive's trajectory: asked for every drive, the server refuses and says why
        box.get_by_test_id("map-export-format").select_option("tum")
        expect(box.get_by_test_id("map-export-drive")).to_have_value("")
        box.get_by_test_id("map-export-download").click()
        error = box.get_by_test_id("map-export-error")
        expect(error).to_contain_text("The server refused the export")
        expect(error).to_contain_text("pick one drive")
        expect(error).to_have_attribute("role", "alert")
        assert downloads == []

        # one drive: the file, and the error is gone
        drive = box.get_by_test_id("map-export-drive").locator("option").nth(1).get_attribute("value") or ""
        box.get_by_test_id("map-export-drive").select_option(drive)
        name, data = download_through(p, box.get_by_test_id("map-export-download"))
        assert name == f"tiny-map-v1-{drive}.tum.txt"
        lines = [line for line in data.decode().splitlines() if not line.startswith("#")]
        assert all(len(line.split()) == 8 for line in lines)  # timestamp tx ty tz qx qy qz qw
        expect(error).to_have_count(0)
        # the browser logged the refused request, and nothing else
        assert all(re.search(r" 4\d\d ", e) for e in page.errors), page.errors


class TestPositionsExport:
    def test_download_the_selected_vehicles_history_then_every_vehicles(
        self, server: Server, page: PageWithLog, fleet: dict[str, Vehicle]
    ) -> None:
        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-monitor").click()
        box = p.get_by_test_id("positions-export")
        vehicle = box.get_by_test_id("positions-export-vehicle")
        expect(vehicle).to_have_value("")  # nothing selected: every vehicle
        p.get_by_test_id("vehicle-row-haul-truck-07").click()
        expect(vehicle).to_have_value("haul-truck-07")  # follows the selection
        # the range shown: the history's last five minutes, written as the replay's inputs are
        expect(box.get_by_test_id("positions-export-from")).to_have_value(CLOCK_TEXT)
        expect(box.get_by_test_id("positions-export-to")).to_have_value(CLOCK_TEXT)

        name, data = download_through(p, box.get_by_test_id("positions-export-download"))
        assert name == "tiny-positions-haul-truck-07.csv"
        expected = server.api(
            "GET", "/api/sites/1/positions/export", params={"format": "csv", "vehicle": "haul-truck-07"}
        )
        assert data == expected.content
        rows = list(csv.DictReader(io.StringIO(data.decode())))
        assert data.decode().splitlines()[0] == POSITIONS_HEADER
        assert len(rows) == FRAMES
        assert {r["vehicle"] for r in rows} == {"haul-truck-07"}

        # a narrower range: only the positions in it
        first_t = float(rows[0]["t"])
        box.get_by_test_id("positions-export-from").fill(str(first_t + 0.25))
        _, data = download_through(p, box.get_by_test_id("positions-export-download"))
        narrowed = list(csv.DictReader(io.StringIO(data.decode())))
        assert [r["t"] for r in narrowed] == [r["t"] for r in rows if float(r["t"]) >= first_t + 0.25]
        box.get_by_test_id("positions-export-shown").click()  # back to the range shown
        expect(box.get_by_test_id("positions-export-from")).to_have_value(CLOCK_TEXT)

        vehicle.select_option("")
        box.get_by_test_id("positions-export-format").select_option("geojson")
        name, data = download_through(p, box.get_by_test_id("positions-export-download"))
        assert name == "tiny-positions.geojson"
        collection = json.loads(data)
        assert collection["type"] == "FeatureCollection"
        tracks = {f["properties"]["vehicle"]: len(f["properties"]["t_s"]) for f in collection["features"]}
        assert tracks == dict.fromkeys(fleet, FRAMES)
        screenshot(p, "ui_positions_export")
        assert page.errors == []

    def test_an_unreadable_time_and_a_refusal_are_explained(
        self, server: Server, page: PageWithLog, fleet: dict[str, Vehicle]
    ) -> None:
        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-monitor").click()
        box = p.get_by_test_id("positions-export")
        expect(p.get_by_test_id("vehicle-row-lhd-2")).to_be_visible()
        box.get_by_test_id("positions-export-from").fill("yesterday")
        box.get_by_test_id("positions-export-download").click()
        expect(box.get_by_test_id("positions-export-error")).to_contain_text("Write times as")

        # TUM holds one vehicle's trajectory: asked for every vehicle, the server refuses and says why
        box.get_by_test_id("positions-export-shown").click()
        box.get_by_test_id("positions-export-format").select_option("tum")
        box.get_by_test_id("positions-export-download").click()
        error = box.get_by_test_id("positions-export-error")
        expect(error).to_contain_text("The server refused the export")
        expect(error).to_contain_text("pick one vehicle")
        expect(error).to_have_attribute("role", "alert")
        assert all(re.search(r" 4\d\d ", e) for e in page.errors), page.errors

    def test_the_range_follows_a_loaded_replay(
        self, server: Server, page: PageWithLog, tiny_site_dir: Path, fleet: dict[str, Vehicle]
    ) -> None:
        vehicle = Vehicle(
            server, "drive-clock-1"
        )  # a recorded drive's clock: tenths of a second in the inputs
        for i, frame in enumerate(recorded_frames(localisation_drive(tiny_site_dir), FRAMES)):
            assert vehicle.post(500.0 + FRAME_PERIOD_S * i, frame.data)["status"] == "processed"
        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-monitor").click()
        p.get_by_test_id("vehicle-row-drive-clock-1").click()
        box = p.get_by_test_id("positions-export")
        expect(box.get_by_test_id("positions-export-to")).to_have_value("+0:08:20.7")
        p.get_by_test_id("replay-from").fill("+0:08:20.2")
        p.get_by_test_id("replay-to").fill("+0:08:20.5")
        p.get_by_test_id("replay-load").click()
        expect(p.get_by_test_id("replay-panel")).to_have_attribute("data-count", "4")
        expect(box.get_by_test_id("positions-export-from")).to_have_value("+0:08:20.2")
        expect(box.get_by_test_id("positions-export-to")).to_have_value("+0:08:20.5")
        _, data = download_through(p, box.get_by_test_id("positions-export-download"))
        rows = list(csv.DictReader(io.StringIO(data.decode())))
        assert [round(float(r["t"]), 1) for r in rows] == [500.2, 500.3, 500.4, 500.5]
        # back to live: the history's window again
        p.get_by_test_id("replay-close").click()
        expect(box.get_by_test_id("positions-export-from")).to_have_value("+0:03:20.7")
        assert page.errors == []


class TestLastSeen:
    @pytest.mark.parametrize("width", WIDE_VIEWPORTS)
    def test_the_list_shows_last_seen_and_every_column_fits(
        self, server: Server, browser: Browser, fleet: dict[str, Vehicle], width: int
    ) -> None:
        context = browser.new_context(viewport={"width": width, "height": VIEWPORT_H})
        try:
            p = context.new_page()
            log_in(p, server)
            p.get_by_test_id("nav-monitor").click()
            header = p.get_by_test_id("vehicle-list").locator("th").last
            expect(header).to_have_text("Last seen")
            row = p.get_by_test_id("vehicle-row-haul-truck-07")
            cell = row.get_by_test_id("last-seen")
            expect(cell).to_have_text(re.compile(r"^(\d+ s|\d+ min)$"))
            expect(cell).to_have_attribute("title", re.compile(r"^Last position received \d\d:\d\d:\d\d$"))
            # it counts up between messages (the fleet posts nothing more)
            age = int(cell.get_attribute("data-age-s") or "-1")
            assert age >= 0
            expect(cell).not_to_have_attribute("data-age-s", str(age), timeout=5_000)

            # every column inside the side panel: nothing cut off, no sideways scrolling
            screenshot(p, f"ui_last_seen_{width}")
            side = p.locator("aside.side")
            panel = side.bounding_box()
            assert panel is not None
            for th in p.get_by_test_id("vehicle-list").locator("th").all():
                box = th.bounding_box()
                assert box is not None
                assert box["x"] + box["width"] <= panel["x"] + panel["width"] + 0.5, (th.inner_text(), box)
            assert side.evaluate("el => el.scrollWidth <= el.clientWidth"), "the side panel scrolls sideways"
        finally:
            context.close()
