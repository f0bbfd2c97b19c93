"""The camera set-up page in the browser, as a surveyor: a floor frame uploaded, the ground region dragged, a lens
pasted (the undistorted preview appears with the region on it), four floor marks clicked and measured, the ground
fitted (the homography the frame was drawn with comes back, the bird's-eye preview appears), the camera saved as a
profile and given to a vehicle; and collinear points refused with the server's reason, the
form kept. Against a real ``driftmap serve`` over an empty data directory (no map is needed), with the
``browser`` and ``page`` fixtures of ``conftest.py``.

Every wait polls the DOM or the API up to a deadline (Playwright's ``expect``); nothing sleeps for a fixed time.
"""

from __future__ import annotations

import json
import re
from collections.abc import Iterator
from pathlib import Path

import cv2
import numpy as np
import pytest
from playwright.sync_api import Page, expect

from tests.e2e.conftest import (
    ADMIN_PASSWORD,
    PageWithLog,
    Server,
    add_user,
    admin_server,
    chromium_path,
    ensure_frontend_built,
    screenshot,
)
from tests.processes import driftmap_env

pytestmark = pytest.mark.slow  # a real server and a browser

WIDTH, HEIGHT = 320, 240
# floor (x_m forward, y_m left, w) = H (u, v, 1): x_m = 600 / (v - 40), y_m = 3 (160 - u) / (v - 40)
FLOOR_FROM_PIXEL = np.array([[0.0, 0.0, 600.0], [-3.0, 0.0, 480.0], [0.0, 1.0, -40.0]])
MARKS_PX = [(60.0, 120.0), (260.0, 120.0), (40.0, 220.0), (280.0, 220.0)]  # spread over the floor in view
COLLINEAR_PX = [(40.0, 150.0), (120.0, 150.0), (200.0, 150.0), (280.0, 150.0)]  # one image row
REGION_DRAG_PX = ((8.0, 100.0), (312.0, 236.0))
CLICK_TOLERANCE_PX = 0.6  # a click's frame pixel, read back from the table (shown to 0.1 px)
RESIDUAL_TOLERANCE_M = 0.01
FLOOR_TOLERANCE_M = 0.02  # the fitted homography against the true one, over the region
PROFILE = "rear-cam-320"
# a lens without distortion: its undistorted image is the frame, so the floor points fit exactly as drawn
LENS = {
    "model": "pinhole",
    "K": [[300.0, 0.0, 160.0], [0.0, 300.0, 120.0], [0.0, 0.0, 1.0]],
    "distortion": [0.0] * 4,
}


def floor_of(u: float, v: float, h: np.ndarray = FLOOR_FROM_PIXEL) -> tuple[float, float]:
    x, y, w = h @ np.array([u, v, 1.0])
    return float(x / w), float(y / w)


def floor_frame(path: Path) -> Path:
    """A 320x240 PNG of a floor with a 1 m grid seen through FLOOR_FROM_PIXEL, and the marks as rings."""
    image = np.full((HEIGHT, WIDTH, 3), 70, np.uint8)
    image[:40] = 25  # beyond the horizon
    pixel_from_floor = np.linalg.inv(FLOOR_FROM_PIXEL)

    def pixel(x: float, y: float) -> tuple[int, int]:
        u, v, w = pixel_from_floor @ np.array([x, y, 1.0])
        return round(u / w), round(v / w)

    for x in range(3, 16):
        cv2.line(image, pixel(x, -10), pixel(x, 10), (150, 150, 150), 1, cv2.LINE_AA)
    for y in range(-10, 11):
        cv2.line(image, pixel(2.6, y), pixel(15, y), (150, 150, 150), 1, cv2.LINE_AA)
    for u, v in MARKS_PX:
        cv2.circle(image, (round(u), round(v)), 4, (255, 255, 255), 1, cv2.LINE_AA)
    cv2.imwrite(str(path), image)
    return path


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """``driftmap serve`` (no job worker) over a new data directory with one site, a vehicle and a surveyor."""
    if chromium_path() is None:
        pytest.skip("chromium is not installed (make test installs it with apt-get)")
    ensure_frontend_built()
    work = tmp_path_factory.mktemp("e2e-cameras")
    env = driftmap_env(work / "data")
    users = (
        ("admin", "admin", ADMIN_PASSWORD),
        ("surveyor", "surveyor", "surveyor-pw"),
        ("guard", "viewer", "guard-pw"),
    )
    for name, role, password in users:
        add_user(env, name, role, password)
    with admin_server(env, work / "serve.log") as running:
        site = running.api("POST", "/api/sites", json={"name": "east", "description": ""})
        assert site.status_code == 201, site.text
        made = running.api("POST", "/api/vehicles", json={"name": "lhd-4", "site_id": site.json()["id"]})
        assert made.status_code == 201, made.text
        yield running


@pytest.fixture(scope="module")
def frame_png(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return floor_frame(tmp_path_factory.mktemp("frames") / "floor.png")


def log_in(page: Page, server: Server, username: str, password: str) -> None:
    """Log in, asking for the Cameras page in the address (the site has no survey plan, whose page would
    answer 404 for its layers)."""
    page.goto(f"{server.base}/#cameras")
    page.fill("#username", username)
    page.fill("#password", password)
    page.click("button[type=submit]")
    expect(page.get_by_test_id("whoami")).to_contain_text(username)


def open_cameras_page(page: Page, server: Server, frame: Path) -> None:
    """Log in as the surveyor, open the Cameras page and upload the frame."""
    log_in(page, server, "surveyor", "surveyor-pw")
    expect(page.get_by_test_id("nav-cameras")).to_have_class("active")
    page.get_by_test_id("camera-frames-input").set_input_files(str(frame))
    expect(page.get_by_test_id("camera-frame-size")).to_contain_text(f"{WIDTH}x{HEIGHT}")


def page_xy(page: Page, px: float, py: float) -> tuple[float, float]:
    """The page position of a frame pixel, as the frame is shown (scaled)."""
    box = page.get_by_test_id("camera-overlay").bounding_box()
    assert box is not None
    return box["x"] + px * box["width"] / WIDTH, box["y"] + py * box["height"] / HEIGHT


def click_points(page: Page, marks: list[tuple[float, float]]) -> None:
    """Click each mark on the frame and type its true floor position into its row."""
    page.get_by_test_id("camera-mode-points").click()
    for i, (u, v) in enumerate(marks, start=1):
        page.mouse.click(*page_xy(page, u, v))
        row = page.get_by_test_id(f"camera-point-{i}")
        expect(row).to_be_visible()
        cells = row.locator("td")
        assert abs(float(cells.nth(1).inner_text()) - u) < CLICK_TOLERANCE_PX
        assert abs(float(cells.nth(2).inner_text()) - v) < CLICK_TOLERANCE_PX
        x_m, y_m = floor_of(u, v)
        page.get_by_test_id(f"camera-point-{i}-x_m").fill(f"{x_m:.5f}")
        page.get_by_test_id(f"camera-point-{i}-y_m").fill(f"{y_m:.5f}")


class TestCameraSetUp:
    def test_fit_the_ground_save_a_profile_and_give_it_to_a_vehicle(
        self, server: Server, page: PageWithLog, frame_png: Path
    ) -> None:
        p = page.page
        open_cameras_page(p, server, frame_png)

        # the ground region: a drag over the floor
        p.get_by_test_id("camera-mode-region").click()
        (u0, v0), (u1, v1) = REGION_DRAG_PX
        p.mouse.move(*page_xy(p, u0, v0))
        p.mouse.down()
        p.mouse.move(*page_xy(p, u1, v1), steps=5)
        p.mouse.up()
        expect(p.get_by_test_id("camera-roi")).to_be_visible()
        text = p.get_by_test_id("camera-frame-size").inner_text()
        roi = [int(s) for s in text.split("region ")[1].split(", ")]
        assert roi[0] in (7, 8) and roi[1] in (99, 100)
        assert abs(roi[0] + roi[2] - u1) <= 1 and abs(roi[1] + roi[3] - v1) <= 1

        # the lens, pasted: the undistorted preview shows the region where it lies
        p.get_by_test_id("camera-lens-paste").check()
        p.get_by_test_id("camera-lens-text").fill(json.dumps(LENS))
        p.get_by_role("button", name="Use this lens").click()
        expect(p.get_by_test_id("camera-lens-current")).to_contain_text("pinhole, f 300.0 px")
        expect(p.get_by_test_id("camera-preview-undistorted")).to_be_visible()
        expect(p.get_by_test_id("camera-preview-roi")).to_have_attribute("width", str(roi[2]))
        expect(p.get_by_test_id("camera-preview-birdseye")).to_have_count(0)  # no fit yet

        click_points(p, MARKS_PX)
        p.get_by_test_id("camera-fit-button").click()
        expect(p.get_by_test_id("camera-k-x")).to_contain_text("m/px")
        expect(p.get_by_test_id("camera-k-y")).to_contain_text("m/px")
        # the floor from above, at a millimetre-whole scale, the region's footprint outlined
        expect(p.get_by_test_id("camera-preview-birdseye")).to_be_visible()
        expect(p.get_by_test_id("camera-preview-birdseye-caption")).to_contain_text(
            "the way the camera looks"
        )
        expect(p.get_by_test_id("camera-preview-footprint")).to_have_attribute(
            "points", re.compile(r"^(\S+ ){3}\S+$")
        )
        shown = p.get_by_test_id("camera-preview-birdseye").locator("img")
        assert shown.evaluate("img => img.complete && img.naturalWidth > 0 && img.naturalHeight > 0")
        for i in range(1, len(MARKS_PX) + 1):
            residual = p.get_by_test_id(f"camera-point-{i}-residual").inner_text()
            assert float(residual.removesuffix(" m")) < RESIDUAL_TOLERANCE_M, residual

        # saved under a name, then given to the vehicle
        p.get_by_test_id("camera-profile-name").fill(PROFILE)
        p.get_by_test_id("camera-profile-create").click()
        expect(p.get_by_test_id("camera-profiles-done")).to_have_text(f"Saved profile {PROFILE}")
        expect(p.get_by_test_id(f"camera-profile-{PROFILE}")).to_have_class("selected")
        vehicle = next(v for v in server.api("GET", "/api/vehicles").json() if v["name"] == "lhd-4")
        p.get_by_test_id("camera-vehicle").select_option(str(vehicle["id"]))
        p.get_by_test_id("camera-assign").click()
        expect(p.get_by_test_id("camera-profiles-done")).to_contain_text(
            f"lhd-4 now has the camera of {PROFILE}"
        )
        p.get_by_test_id("cameras-page").evaluate("page => page.scrollTo(0, 0)")
        screenshot(p, "ui_cameras")

        camera = server.api("GET", f"/api/vehicles/{vehicle['id']}/camera")
        assert camera.status_code == 200, camera.text
        block = camera.json()
        profile = next(
            q for q in server.api("GET", "/api/camera-profiles").json()["items"] if q["name"] == PROFILE
        )
        assert block == profile["camera"]
        assert (block["width"], block["height"], block["ground_roi"]) == (WIDTH, HEIGHT, roi)
        assert block["lens"] == LENS
        assert f"{block['k_x']:.5f}" in p.get_by_test_id("camera-k-x").inner_text()
        fitted = np.array(block["ground_homography"])
        for u in np.linspace(roi[0], roi[0] + roi[2], 5):
            for v in np.linspace(roi[1], roi[1] + roi[3], 5):
                assert np.allclose(floor_of(u, v, fitted), floor_of(u, v), atol=FLOOR_TOLERANCE_M)
        assert page.errors == []

    def test_collinear_points_are_refused_with_the_servers_reason(
        self, server: Server, page: PageWithLog, frame_png: Path
    ) -> None:
        p = page.page
        open_cameras_page(p, server, frame_png)
        click_points(p, COLLINEAR_PX)
        with p.expect_response(lambda r: r.url.endswith("/api/cameras/ground")) as answer:
            p.get_by_test_id("camera-fit-button").click()
        assert answer.value.status == 422
        error = p.get_by_test_id("camera-fit-error")
        expect(error).to_contain_text("collinear")
        expect(error).to_contain_text("points")
        expect(error).to_have_attribute("role", "alert")
        # nothing lost: the four rows and their typed floor positions are still there
        expect(p.get_by_test_id("camera-points").locator("tbody tr")).to_have_count(len(COLLINEAR_PX))
        x_m, _ = floor_of(*COLLINEAR_PX[3])
        expect(p.get_by_test_id("camera-point-4-x_m")).to_have_value(f"{x_m:.5f}")
        expect(p.get_by_test_id("camera-fit-result")).to_have_count(0)
        expect(p.get_by_test_id("camera-profile-create")).to_be_disabled()
        assert all(" 422 " in e for e in page.errors), page.errors

    def test_a_viewer_has_no_cameras_page(self, server: Server, page: PageWithLog) -> None:
        p = page.page
        log_in(p, server, "guard", "guard-pw")
        expect(p.get_by_test_id("nav-grounding")).to_be_visible()
        expect(p.get_by_test_id("nav-cameras")).to_have_count(0)
        expect(p.get_by_test_id("cameras-page")).to_have_count(0)
