"""The Cameras page's check against a stored drive, in the browser as a surveyor: a drive of rendered frames that
goes straight and then turns 46 degrees left about a point 0.5 m behind the camera, whose drive.json block says
the camera is 1.5 m from the rear axle and looks behind (forward_sign -1; the frames were drawn looking ahead).
A turn check of 45 degrees finds the lever near 0.5 m and forward_sign wrong; the corrected camera taken into the
page changes its y_c and forward_sign and is saved as a profile. A turn of 5 degrees is refused with the server's
reason naming turn_deg, the form kept. Against a real ``driftmap serve`` over a new data directory, the drive
imported with ``driftmap drive import``; the ``browser`` and ``page`` fixtures of ``conftest.py``.

Every wait polls the DOM or the API up to a deadline (Playwright's ``expect``); nothing sleeps for a fixed time.
"""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from collections.abc import Iterator

import pytest
from playwright.sync_api import Page, expect

from driftmap.formats.drive_folder import write_drive_folder
from driftmap.formats.frame_images import encode_png
from driftmap.formats.records import DriveMeta, FrameRow
from tests.core.odometry.test_turn_check import TRUE_Y_C_M, Y_C_TOL_M, straight_then_turn
from tests.e2e.conftest import (
    PageWithLog,
    Server,
    add_user,
    admin_server,
    chromium_path,
    ensure_frontend_built,
    screenshot,
)
from tests.floor_frames import pinhole_camera
from tests.processes import driftmap_env

pytestmark = pytest.mark.slow  # a real server and a browser

SITE, DRIVE = "check", "turn"
STATED_Y_C_M = 1.5  # the lever pinhole_camera() and so the drive's block says
CHECK_DEADLINE_MS = 60_000  # the server dead-reckons the drive while the request waits
SURVEYOR = ("surveyor", "surveyor-pw")
PROFILE = "turn-checked"


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Server]:
    """``driftmap serve`` (no job worker) over a new data directory with a surveyor and one site holding the
    straight-then-turn drive, its camera saying forward_sign -1."""
    if chromium_path() is None:
        pytest.skip("chromium is not installed (make test installs it with apt-get)")
    ensure_frontend_built()
    work = tmp_path_factory.mktemp("e2e-camera-check")
    env = driftmap_env(work / "data")
    add_user(env, "admin", "admin", "e2e-admin-password")
    add_user(env, SURVEYOR[0], "surveyor", SURVEYOR[1])
    frames = straight_then_turn()
    camera = dataclasses.replace(pinhole_camera(), forward_sign=-1)
    folder = work / DRIVE
    rows = [FrameRow(i, i / 10) for i in range(len(frames))]
    write_drive_folder(folder, DriveMeta(DRIVE, "mapping", 10.0, camera), rows, map(encode_png, frames))
    with admin_server(env, work / "serve.log") as running:
        site = running.api("POST", "/api/sites", json={"name": SITE, "description": ""})
        assert site.status_code == 201, site.text
        imported = subprocess.run(
            [sys.executable, "-m", "driftmap", "drive", "import", SITE, str(folder)],
            env=env,
            capture_output=True,
            check=False,
        )
        assert imported.returncode == 0, imported.stderr.decode()
        yield running


@pytest.fixture(scope="module")
def drive_id(server: Server) -> int:
    site = next(s for s in server.api("GET", "/api/sites").json()["items"] if s["name"] == SITE)
    drives = server.api("GET", f"/api/sites/{site['id']}/drives").json()["items"]
    return int(next(d["id"] for d in drives if d["name"] == DRIVE))


def open_check(page: Page, server: Server, drive_id: int, turn_deg: str) -> None:
    """Log in as the surveyor on the Cameras page, choose the drive and a turn check of ``turn_deg`` degrees."""
    page.goto(f"{server.base}/#cameras")
    page.fill("#username", SURVEYOR[0])
    page.fill("#password", SURVEYOR[1])
    page.click("button[type=submit]")
    expect(page.get_by_test_id("nav-cameras")).to_have_class("active")
    page.get_by_test_id("camera-check-site").select_option(label=SITE)
    expect(page.get_by_test_id("camera-check-drive")).to_have_value(str(drive_id))
    page.get_by_test_id("camera-check-kind").select_option("turn")
    page.get_by_test_id("camera-check-amount").fill(turn_deg)


def metres_in(text: str) -> float:
    """The first number in a line such as ``0.52 ± 0.03 m (the floor's rotation)``."""
    found = re.search(r"[-+]?\d+\.\d+", text)
    assert found is not None, text
    return float(found.group())


class TestCheckAgainstADrive:
    def test_a_turn_finds_the_lever_and_forward_sign_and_the_page_takes_them(
        self, server: Server, page: PageWithLog, drive_id: int
    ) -> None:
        p = page.page
        open_check(p, server, drive_id, "45")
        expect(p.get_by_test_id("camera-check-which")).to_contain_text(f"drive {DRIVE}'s own camera")
        expect(p.get_by_test_id("camera-check-which")).to_contain_text("forward_sign −1")
        expect(p.get_by_test_id("camera-y-c")).to_have_value("0")

        p.get_by_test_id("camera-check-run").click()
        expect(p.get_by_test_id("camera-check-result")).to_be_visible(timeout=CHECK_DEADLINE_MS)
        fitted_m = metres_in(p.get_by_test_id("camera-check-fitted").inner_text())
        assert abs(fitted_m - TRUE_Y_C_M) < Y_C_TOL_M, fitted_m
        stated_turn_m = metres_in(p.get_by_test_id("camera-check-stated-turn").inner_text())
        assert abs(stated_turn_m - TRUE_Y_C_M) < 0.3, stated_turn_m
        expect(p.get_by_test_id("camera-check-sign")).to_contain_text("wrong")
        expect(p.get_by_test_id("camera-check-sign")).to_contain_text("forward_sign +1")
        expect(p.get_by_test_id("camera-check-direction")).to_contain_text("turned the stated way")
        expect(p.get_by_test_id("camera-check-configured")).to_have_text(f"{STATED_Y_C_M:.2f} m")
        screenshot(p, "ui_camera_check")

        # the corrected camera into the page: its lever and forward_sign into the mount's fields
        p.get_by_test_id("camera-check-use").click()
        expect(p.get_by_test_id("camera-check-used")).to_contain_text("forward_sign +1")
        taken_m = float(p.get_by_test_id("camera-y-c").input_value())
        assert abs(taken_m - TRUE_Y_C_M) < Y_C_TOL_M and round(taken_m, 2) == round(fitted_m, 2), taken_m
        expect(p.get_by_test_id("camera-looks")).to_have_value("1")
        expect(p.get_by_test_id("camera-check-use")).to_be_disabled()  # the page's camera changed
        expect(p.get_by_test_id("camera-check-which")).to_contain_text("the camera on this page")

        # and saved as a profile: the drive's block with the lever and forward_sign found
        p.get_by_test_id("camera-profile-name").fill(PROFILE)
        p.get_by_test_id("camera-profile-create").click()
        expect(p.get_by_test_id("camera-profiles-done")).to_have_text(f"Saved profile {PROFILE}")
        profile = next(
            q for q in server.api("GET", "/api/camera-profiles").json()["items"] if q["name"] == PROFILE
        )
        own = server.api("GET", f"/api/drives/{drive_id}").json()["camera"]
        assert profile["camera"] == {"lens": None, **own, "y_c": taken_m, "forward_sign": 1}
        assert page.errors == []

    def test_a_turn_too_small_is_refused_with_the_servers_reason(
        self, server: Server, page: PageWithLog, drive_id: int
    ) -> None:
        p = page.page
        open_check(p, server, drive_id, "5")
        with p.expect_response(lambda r: r.url.endswith("/camera-check")) as answer:
            p.get_by_test_id("camera-check-run").click()
        assert answer.value.status == 422
        error = p.get_by_test_id("camera-check-error")
        expect(error).to_contain_text("turn_deg")
        expect(error).to_contain_text("at least 20 degrees")
        expect(error).to_have_attribute("role", "alert")
        # the form kept, nothing shown as found
        expect(p.get_by_test_id("camera-check-kind")).to_have_value("turn")
        expect(p.get_by_test_id("camera-check-amount")).to_have_value("5")
        expect(p.get_by_test_id("camera-check-drive")).to_have_value(str(drive_id))
        expect(p.get_by_test_id("camera-check-result")).to_have_count(0)
        expect(p.get_by_test_id("camera-check-run")).to_be_enabled()
        assert all(" 422 " in e for e in page.errors), page.errors
