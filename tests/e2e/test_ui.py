"""The browser UI against a real server: login, survey layers, roles, live monitoring, grounding, admin.

Every wait polls the DOM or the API up to a deadline (Playwright's ``expect``); nothing sleeps for a fixed time.
"""

from __future__ import annotations

import json
import math
import re
import time
from pathlib import Path
from typing import Any

import cv2
import pytest
from playwright.sync_api import Page, Request, expect

from tests.api.access_helpers import localisation_drive, recorded_frames
from tests.e2e.conftest import ADMIN_PASSWORD, PageWithLog, Server, screenshot
from tests.e2e.map_helpers import (
    distance_to_lines,
    inside_walls,
    layer_lines,
    map_scale,
    metres_per_pixel,
    pixel_of,
    plain_map_at,
)
from tests.jobs.mini_site import zip_folder

pytestmark = pytest.mark.slow  # a real server and a browser

DEADLINE_S = 60.0
FRAME_PERIOD_S = 0.1  # the posted frames' spacing in vehicle time, seconds
BUILD_DEADLINE_MS = 300_000  # a FAST map build of the tiny site on a busy 2-core machine
FAR_CLICK_M = 25.0  # a stray click this far from the keyframe's estimate (the UI asks beyond 15 m)
WALL_MARGIN_M = (
    1.0  # the far click lies this far outside the walls (the UI checks the plan as loaded, simplified)
)
PICK_CLEARANCE_PX = 20  # a keyframe picked for grounding lies this far from every grounding's square


WATCH_BUILD_JOB = """() => {
  window.buildJobShown = [];
  const record = () => {
    const job = document.querySelector('[data-testid="build-job"]');
    if (!job) return;
    const seen = [job.dataset.progress, job.textContent];
    const last = window.buildJobShown[window.buildJobShown.length - 1];
    if (!last || last[0] !== seen[0] || last[1] !== seen[1]) window.buildJobShown.push(seen);
  };
  new MutationObserver(record).observe(document.body, {
    subtree: true, childList: true, characterData: true, attributes: true,
  });
}"""
"""Records each (data-progress, text) the build job's line shows from now on, in ``window.buildJobShown``."""


WATCH_UPLOAD = """(testId) => {
  window.uploadShown = [];
  new MutationObserver(() => {
    const box = document.querySelector(`[data-testid="${testId}"]`);
    if (!box) return;
    const seen = [box.dataset.state, box.querySelector("span")?.textContent ?? ""];
    const last = window.uploadShown[window.uploadShown.length - 1];
    if (!last || last[0] !== seen[0] || last[1] !== seen[1]) window.uploadShown.push(seen);
  }).observe(document.body, { subtree: true, childList: true, characterData: true, attributes: true });
}"""
"""Records each (data-state, text) an upload's progress line shows from now on, in ``window.uploadShown``."""


def log_in(page: Page, server: Server, username: str, password: str) -> None:
    page.goto(f"{server.base}/")
    page.fill("#username", username)
    page.fill("#password", password)
    page.click("button[type=submit]")
    expect(page.get_by_test_id("whoami")).to_contain_text(username)


def grid_readout(page: Page) -> tuple[float, float]:
    """The easting and northing shown under the pointer."""
    text = page.get_by_test_id("grid-readout").inner_text()
    match = re.search(r"E (-?[\d.]+)\s+N (-?[\d.]+)", text)
    assert match, text
    return float(match.group(1)), float(match.group(2))


def make_user(server: Server, name: str, role: str) -> str:
    password = f"{name}-password"
    created = server.api("POST", "/api/users", json={"username": name, "password": password, "role": role})
    assert created.status_code in (200, 201), created.text
    return password


def wait_for_number(page: Page, test_id: str, attribute: str, value: float, tolerance: float = 0.002) -> None:
    """Wait until the element's ``attribute`` holds a number within ``tolerance`` of ``value``."""
    element = page.get_by_test_id(test_id)
    deadline = time.monotonic() + DEADLINE_S
    while True:
        text = element.get_attribute(attribute)
        if text is not None and abs(float(text) - value) <= tolerance:
            return
        assert time.monotonic() < deadline, f"{test_id} {attribute} is {text}, not {value}"
        page.wait_for_timeout(100)


def groundings(server: Server) -> list[dict[str, Any]]:
    items: list[dict[str, Any]] = server.api("GET", "/api/sites/1/groundings").json()["items"]
    return items


def watch_grounding_writes(page: Page) -> list[tuple[str, int]]:
    """The grounding writes (POST /api/drives/{id}/groundings) the page sends from now on: (method, drive id)."""
    sent: list[tuple[str, int]] = []

    def on_request(request: Request) -> None:
        found = re.search(r"/api/drives/(\d+)/groundings$", request.url)
        if found and request.method == "POST":
            sent.append((request.method, int(found.group(1))))

    page.on("request", on_request)
    return sent


def pick_ungrounded_keyframe(
    page: Page, server: Server, grounded: list[dict[str, Any]]
) -> tuple[int, int, tuple[float, float]]:
    """Select a keyframe of the strip's first page that has no grounding, far from every grounding's square and
    with its estimate on plain map; returns its drive, frame and the estimate's page pixel."""
    thumbs = page.get_by_test_id("keyframe-strip").locator("[data-frame]")
    expect(thumbs.first).to_be_visible()  # drawn once the drives have loaded
    expect(page.get_by_test_id("map")).to_have_attribute("data-ready", "yes")
    drive_id = int(page.get_by_test_id("drive-select").input_value())
    poses = server.api("GET", "/api/sites/1/maps/1/poses").json()
    estimate = {
        (d, f): (x, y)
        for d, f, x, y in zip(poses["drive_id"], poses["frame"], poses["x_m"], poses["y_m"], strict=True)
    }
    taken = {(g["drive_id"], g["frame"]) for g in grounded}
    frames = [int(t.get_attribute("data-frame") or "-1") for t in thumbs.all()]

    def clearance(f: int) -> float:
        ex, ey = estimate[(drive_id, f)]
        return min(
            (math.hypot(float(g["x_m"]) - ex, float(g["y_m"]) - ey) for g in grounded), default=math.inf
        )

    candidates = sorted((f for f in frames if (drive_id, f) not in taken), key=clearance, reverse=True)
    m_per_px = metres_per_pixel(page)
    for frame in candidates:
        assert clearance(frame) > PICK_CLEARANCE_PX * m_per_px, "every free keyframe is next to a grounding"
        at = pixel_of(page, *estimate[(drive_id, frame)])
        if plain_map_at(page, *at):
            page.get_by_test_id(f"keyframe-{frame}").click()
            expect(page.get_by_test_id("selected-frame")).to_have_attribute("data-frame", str(frame))
            return drive_id, frame, at
    raise AssertionError("no free keyframe on plain map")


def far_pixel(
    page: Page, server: Server, near: tuple[float, float], distance_m: float
) -> tuple[float, float]:
    """A plain-map pixel at least ``distance_m`` from ``near`` and clearly outside the plan's walls (in rock)."""
    walls = layer_lines(server, "WALLS")
    ax, ay, ea, na, m_per_px = map_scale(page)
    for scale in (1.0, 1.5, 2.0):
        offset = scale * distance_m / m_per_px
        for angle in range(0, 360, 10):
            a = math.radians(angle)
            at = (near[0] + offset * math.cos(a), near[1] + offset * math.sin(a))
            world = (ea + (at[0] - ax) * m_per_px, na - (at[1] - ay) * m_per_px)
            in_rock = not inside_walls(world, walls) and distance_to_lines(world, walls) > WALL_MARGIN_M
            if in_rock and plain_map_at(page, *at):
                return at
    raise AssertionError(f"no plain map in rock {distance_m} m from {near}")


class TestLoginAndSurvey:
    def test_wrong_password_then_survey_layers_toggle_readout_and_fit(
        self, server: Server, page: PageWithLog
    ) -> None:
        p = page.page
        zooms: list[int] = []
        p.on(
            "request",
            lambda r: zooms.extend(int(z) for z in re.findall(r"survey/layers\?zoom=(\d+)", r.url)),
        )
        p.goto(f"{server.base}/")
        p.fill("#username", "admin")
        p.fill("#password", "not-the-password")
        p.click("button[type=submit]")
        expect(p.get_by_test_id("login-error")).to_contain_text("wrong user name or password")
        page.errors.clear()  # the browser logs the expected 401

        log_in(p, server, "admin", ADMIN_PASSWORD)
        layers = server.api("GET", "/api/sites/1/survey/layers").json()
        for name in layers["layers"]:
            expect(p.get_by_test_id(f"layer-toggle-{name}")).to_be_checked()
        first = sorted(layers["layers"])[0]
        p.get_by_test_id(f"layer-toggle-{first}").uncheck()
        expect(p.get_by_test_id(f"layer-toggle-{first}")).not_to_be_checked()
        p.get_by_test_id(f"layer-toggle-{first}").check()

        p.get_by_test_id("fit-site").click()
        box = p.get_by_test_id("map").bounding_box()
        assert box is not None
        p.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        expect(p.get_by_test_id("grid-readout")).to_contain_text("E ")
        x, y = grid_readout(p)
        min_x, min_y, max_x, max_y = layers["extents"]
        assert min_x <= x <= max_x and min_y <= y <= max_y, (x, y, layers["extents"])
        # a coarse plan first, then the detail of the fitted view (half a pixel; the tiny plan fits zoom >= 1)
        deadline = time.monotonic() + DEADLINE_S
        while max(zooms, default=0) < 1:
            assert time.monotonic() < deadline, f"no detailed survey request, zooms asked: {zooms}"
            p.wait_for_timeout(100)
        assert zooms[0] == 0
        screenshot(p, "ui_survey")
        assert page.errors == []

    def test_the_plans_text_labels_are_drawn_and_toggle_with_their_layer(
        self, server: Server, page: PageWithLog
    ) -> None:
        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        plan = p.get_by_test_id("map")
        expect(plan).to_have_attribute("data-ready", "yes")
        layers = server.api("GET", "/api/sites/1/survey/layers").json()["layers"]
        texts = [f for f in layers["LABELS"]["features"] if f["properties"].get("text")]
        expect(plan).to_have_attribute("data-labels", str(len(texts)))
        label = texts[0]
        at = pixel_of(p, *label["geometry"]["coordinates"])
        for _ in range(4):  # close enough for the lettering (its DXF height in metres) to be readable
            p.mouse.move(*at)
            p.mouse.wheel(0, -300)
            p.wait_for_timeout(300)  # the wheel zoom animates
        at = pixel_of(p, *label["geometry"]["coordinates"])
        clip = {"x": at[0] - 60, "y": at[1] - 20, "width": 120, "height": 40}
        p.mouse.move(1, 1)
        shown = p.screenshot(clip=clip)
        p.get_by_test_id("layer-toggle-LABELS").uncheck()
        p.wait_for_timeout(300)
        hidden = p.screenshot(clip=clip)
        assert shown != hidden, "the label drew nothing"
        p.get_by_test_id("layer-toggle-LABELS").check()
        assert page.errors == []


class TestRoles:
    def test_viewer_sees_no_editing_controls(self, server: Server, page: PageWithLog) -> None:
        password = make_user(server, "watcher", "viewer")
        p = page.page
        log_in(p, server, "watcher", password)
        expect(p.get_by_test_id("nav-survey")).to_be_visible()
        expect(p.get_by_test_id("nav-admin")).to_have_count(0)
        p.get_by_test_id("nav-grounding").click()
        expect(p.get_by_test_id("groundings-table").locator("tbody tr").first).to_be_visible()
        expect(p.get_by_test_id("build-map")).to_have_count(0)
        expect(p.get_by_test_id("undo")).to_have_count(0)
        expect(p.locator("[data-testid^=delete-grounding-]")).to_have_count(0)
        p.keyboard.press("?")
        expect(p.get_by_test_id("help-overlay")).to_contain_text("next keyframe")
        p.keyboard.press("Escape")
        expect(p.get_by_test_id("help-overlay")).to_have_count(0)
        # monitoring: a viewer sees a vehicle's details but cannot place its start
        made = server.api("POST", "/api/vehicles", json={"name": "watched-1", "site_id": 1})
        assert made.status_code in (200, 201), made.text
        p.get_by_test_id("nav-monitor").click()
        p.get_by_test_id("vehicle-row-watched-1").click()
        expect(p.get_by_test_id("vehicle-details")).to_contain_text("watched-1")
        expect(p.get_by_test_id("set-start")).to_have_count(0)
        assert page.errors == []


class TestMonitoring:
    def test_two_vehicles_update_and_one_turns_stale(
        self, server: Server, page: PageWithLog, tiny_site_dir: Path
    ) -> None:
        tokens = {}
        for name in ("lhd-a", "lhd-b"):
            made = server.api("POST", "/api/vehicles", json={"name": name, "site_id": 1})
            assert made.status_code in (200, 201), made.text
            tokens[name] = (made.json()["id"], made.json()["token"])
        frames = recorded_frames(localisation_drive(tiny_site_dir), 30)

        def post(name: str, i: int) -> int:
            """Post the ``i``-th frame (images repeat after 30; ``t`` always increases) and return its seq."""
            vehicle_id, token = tokens[name]
            answer = server.api(
                "POST",
                f"/api/vehicles/{vehicle_id}/frames",
                token=token,
                params={"t": FRAME_PERIOD_S * i},
                content=frames[i % len(frames)].data,
                headers={"Content-Type": "image/png"},
            )
            assert answer.status_code == 200, answer.text
            assert answer.json()["status"] == "processed", answer.text
            seq: int = answer.json()["seq"]
            return seq

        def latest(name: str) -> dict[str, Any]:
            rows: list[dict[str, Any]] = server.api("GET", "/api/positions/latest").json()
            return next(v for v in rows if v["vehicle"] == name)

        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-monitor").click()
        expect(p.get_by_test_id("live-connection")).to_have_text("live")

        for i in range(3):
            post("lhd-a", i)
            post("lhd-b", i)
        for name in ("lhd-a", "lhd-b"):
            position = latest(name)["position"]
            row = p.get_by_test_id(f"vehicle-row-{name}")
            expect(row).to_have_attribute("data-seq", str(position["seq"]))
            expect(row).not_to_have_attribute("data-status", "stale")
            expect(row).to_contain_text(f"{position['x']:.1f}")

        # lhd-a keeps reporting, lhd-b goes quiet: b turns stale (greyed, last position kept), a does not
        row_a = p.get_by_test_id("vehicle-row-lhd-a")
        row_b = p.get_by_test_id("vehicle-row-lhd-b")
        deadline = time.monotonic() + DEADLINE_S
        i = 3
        while row_b.get_attribute("data-status") != "stale":
            assert time.monotonic() < deadline, f"lhd-b did not turn stale within {DEADLINE_S} s"
            post("lhd-a", i)
            i += 1
        expect(row_a).to_have_attribute("data-seq", str(post("lhd-a", i)))
        expect(row_a).not_to_have_attribute("data-status", "stale")
        stale_b = latest("lhd-b")
        assert stale_b["stale"] is True
        expect(row_b).to_contain_text(f"{stale_b['position']['x']:.1f}")

        row_a.click()
        expect(p.get_by_test_id("vehicle-details")).to_contain_text("lhd-a")
        expect(p.get_by_test_id("vehicle-history").locator("tbody tr").first).to_be_visible()
        expect(row_a).to_have_attribute("data-seq", str(post("lhd-a", i + 1)))  # live again for the picture
        screenshot(p, "ui_monitoring")
        assert page.errors == []


class TestGrounding:
    def test_ground_a_keyframe_in_placing_mode_undo_redo_delete(
        self, server: Server, page: PageWithLog
    ) -> None:
        before = groundings(server)
        p = page.page
        posts = watch_grounding_writes(p)
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-grounding").click()
        table_rows = p.get_by_test_id("groundings-table").locator("tbody tr")
        expect(table_rows).to_have_count(len(before))
        drive_id, frame, (px, py) = pick_ungrounded_keyframe(p, server, before)
        at = (px, py)

        # a stray click: placing mode is off, so nothing is written and nothing else gets selected
        p.mouse.click(*at)
        expect(p.get_by_test_id("selected-frame")).to_have_attribute("data-frame", str(frame))
        p.get_by_test_id("place-button").click()
        expect(p.get_by_test_id("map")).to_have_attribute("data-placing", "yes")
        expect(p.get_by_test_id("place-hint")).to_contain_text(f"frame {frame}")
        p.keyboard.press("Escape")  # Escape leaves the placing mode
        expect(p.get_by_test_id("map")).to_have_attribute("data-placing", "no")
        p.mouse.click(*at)
        expect(p.get_by_test_id("selected-frame")).to_have_attribute("data-frame", str(frame))

        p.get_by_test_id("place-button").click()
        expect(p.get_by_test_id("map")).to_have_attribute("data-placing", "yes")
        p.mouse.move(*at)
        expect(p.get_by_test_id("grid-readout")).to_contain_text("E ")
        under = p.evaluate("([x, y]) => getComputedStyle(document.elementFromPoint(x, y)).cursor", list(at))
        assert under == "crosshair", under
        x, y = grid_readout(p)
        p.mouse.click(*at)  # on the keyframe's estimate: written without a question

        expect(table_rows).to_have_count(len(before) + 1)
        expect(p.get_by_test_id("map")).to_have_attribute("data-placing", "no")
        assert posts == [("POST", drive_id)], posts  # the stray clicks sent nothing
        new = [g for g in groundings(server) if (g["drive_id"], g["frame"]) == (drive_id, frame)]
        assert len(new) == 1
        assert abs(float(new[0]["x_m"]) - x) < 0.05 and abs(float(new[0]["y_m"]) - y) < 0.05  # type: ignore[arg-type]
        expect(p.get_by_test_id(f"grounding-row-{new[0]['id']}")).to_contain_text("new")

        # residuals of the latest build, sorted by distance (largest first by default)
        residuals = server.api("GET", "/api/sites/1/maps/1/residuals").json()
        largest = max(residuals, key=lambda r: r["distance_m"])
        expect(table_rows.first).to_contain_text(f"{largest['distance_m']:.2f}")
        p.get_by_test_id("sort-distance").click()
        smallest = min(residuals, key=lambda r: r["distance_m"])
        expect(table_rows.first).to_contain_text(f"{smallest['distance_m']:.2f}")
        screenshot(p, "ui_grounding")

        def mine() -> list[dict[str, object]]:
            return [g for g in groundings(server) if (g["drive_id"], g["frame"]) == (drive_id, frame)]

        p.get_by_test_id("undo").click()
        expect(table_rows).to_have_count(len(before))
        assert not mine()
        p.get_by_test_id("redo").click()
        expect(table_rows).to_have_count(len(before) + 1)
        (restored,) = mine()
        assert (restored["x_m"], restored["y_m"]) == (new[0]["x_m"], new[0]["y_m"])
        p.get_by_test_id(f"delete-grounding-{restored['id']}").click()
        expect(table_rows).to_have_count(len(before))
        assert not mine()

        # the keyboard: g enters the placing mode, g again grounds under the pointer, x deletes the grounding
        p.mouse.move(*at)
        p.keyboard.press("g")
        expect(p.get_by_test_id("map")).to_have_attribute("data-placing", "yes")
        p.keyboard.press("g")
        expect(table_rows).to_have_count(len(before) + 1)
        (again,) = mine()
        assert abs(float(again["x_m"]) - x) < 0.05 and abs(float(again["y_m"]) - y) < 0.05  # type: ignore[arg-type]
        p.keyboard.press("x")
        expect(table_rows).to_have_count(len(before))
        assert not mine()
        assert page.errors == []

    def test_a_far_point_is_confirmed_first_and_a_grounded_frame_selects_its_grounding(
        self, server: Server, page: PageWithLog
    ) -> None:
        before = groundings(server)
        p = page.page
        writes = watch_grounding_writes(p)
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-grounding").click()
        table_rows = p.get_by_test_id("groundings-table").locator("tbody tr")
        expect(table_rows).to_have_count(len(before))
        drive_id, frame, near = pick_ungrounded_keyframe(p, server, before)
        far = far_pixel(p, server, near, FAR_CLICK_M)

        def mine() -> list[dict[str, object]]:
            return [g for g in groundings(server) if (g["drive_id"], g["frame"]) == (drive_id, frame)]

        # a click 25 m from the keyframe's estimate asks first; Cancel writes nothing
        p.get_by_test_id("place-button").click()
        p.mouse.click(*far)
        dialog = p.get_by_test_id("confirm-dialog")
        expect(dialog).to_contain_text("m from the keyframe's current estimate (more than 15 m)")
        expect(dialog).to_contain_text("outside the plan's walls")
        p.get_by_test_id("confirm-cancel").click()
        expect(dialog).to_have_count(0)
        expect(p.get_by_test_id("map")).to_have_attribute("data-placing", "no")
        assert writes == [] and not mine()

        # confirmed, it is written where it was clicked
        p.keyboard.press("g")
        p.mouse.move(*far)
        fx, fy = grid_readout(p)
        p.mouse.click(*far)
        expect(dialog).to_be_visible()
        p.get_by_test_id("confirm-ok").click()
        expect(table_rows).to_have_count(len(before) + 1)
        (placed,) = mine()
        assert abs(float(placed["x_m"]) - fx) < 0.05 and abs(float(placed["y_m"]) - fy) < 0.05  # type: ignore[arg-type]
        assert writes == [("POST", drive_id)], writes

        # the grounded frame selects its grounding: placing again moves it (no "already grounded"), then delete
        selected = p.get_by_test_id("selected-grounding")
        expect(selected).to_have_attribute("data-grounding", str(placed["id"]))
        expect(p.get_by_test_id(f"grounding-row-{placed['id']}")).to_have_class(re.compile("selected"))
        expect(p.get_by_test_id("place-button")).to_contain_text("Move")
        p.get_by_test_id("place-button").click()
        p.mouse.click(*near)
        expect(p.get_by_test_id("grounding-message")).to_contain_text("moved the grounding of")
        (moved,) = mine()
        assert moved["id"] == placed["id"]
        assert math.hypot(float(moved["x_m"]) - fx, float(moved["y_m"]) - fy) > FAR_CLICK_M / 2  # type: ignore[arg-type]
        # a click (placing mode off) on a grounding's square selects its keyframe and grounding
        other = next(g for g in before if plain_map_at(p, *pixel_of(p, float(g["x_m"]), float(g["y_m"]))))
        p.mouse.click(*pixel_of(p, float(other["x_m"]), float(other["y_m"])))
        expect(selected).to_have_attribute("data-grounding", str(other["id"]))
        expect(p.get_by_test_id("selected-frame")).to_have_attribute("data-frame", str(other["frame"]))
        p.mouse.click(*near)
        expect(selected).to_have_attribute("data-grounding", str(placed["id"]))
        p.get_by_test_id("delete-selected-grounding").click()
        expect(table_rows).to_have_count(len(before))
        assert not mine()
        assert page.errors == []

    def test_a_point_snapped_to_a_plan_label_takes_its_station(
        self, server: Server, page: PageWithLog
    ) -> None:
        before = groundings(server)
        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-grounding").click()
        drive_id, frame, _ = pick_ungrounded_keyframe(p, server, before)
        layers = server.api("GET", "/api/sites/1/survey/layers").json()["layers"]
        labels = [f for f in layers["LABELS"]["features"] if f["properties"].get("text", "").strip()]
        label, at = next(
            (f, at) for f in labels if plain_map_at(p, *(at := pixel_of(p, *f["geometry"]["coordinates"])))
        )
        station = label["properties"]["text"].strip()

        p.get_by_test_id("toggle-snap").check()
        p.get_by_test_id("place-button").click()
        p.mouse.move(*at)
        expect(p.get_by_test_id("place-station")).to_contain_text(f"snaps to station {station}")
        p.mouse.click(*at)
        dialog = p.get_by_test_id("confirm-dialog")
        message = p.get_by_test_id("grounding-message")
        expect(dialog.or_(message)).to_be_visible()
        if dialog.is_visible():  # the label may lie far from the keyframe's estimate or outside the walls
            expect(p.get_by_test_id("pending-station")).to_contain_text(station)
            p.get_by_test_id("confirm-ok").click()
        expect(message).to_contain_text(f"at station {station}")
        (placed,) = [g for g in groundings(server) if (g["drive_id"], g["frame"]) == (drive_id, frame)]
        assert placed["station"] == station
        assert (placed["x_m"], placed["y_m"]) == pytest.approx(label["geometry"]["coordinates"], abs=1e-6)
        expect(p.get_by_test_id(f"grounding-row-{placed['id']}")).to_contain_text(station)
        assert server.api("DELETE", f"/api/groundings/{placed['id']}").status_code == 204
        assert page.errors == []

    def test_drag_a_grounding_to_adjust_it_then_undo(self, server: Server, page: PageWithLog) -> None:
        def stored(grounding_id: int) -> tuple[float, float]:
            items = server.api("GET", "/api/sites/1/groundings").json()["items"]
            g = next(g for g in items if g["id"] == grounding_id)
            return float(g["x_m"]), float(g["y_m"])

        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-grounding").click()
        expect(p.get_by_test_id("map")).to_have_attribute("data-ready", "yes")
        grounding_id = int(server.api("GET", "/api/sites/1/groundings").json()["items"][0]["id"])
        gx, gy = stored(grounding_id)
        row = p.get_by_test_id(f"grounding-row-{grounding_id}")
        row.click()  # flies to the grounding: its square ends up in the middle of the map
        box = p.get_by_test_id("map").bounding_box()
        assert box is not None
        centre = (box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        resolution = float("nan")
        deadline = time.monotonic() + DEADLINE_S
        previous: tuple[float, float] | None = None
        clicked = time.monotonic()
        while True:  # until the flight has ended on the grounding (the readout under the centre stops moving)
            assert time.monotonic() < deadline, (
                f"not on the grounding {(gx, gy)}: {previous}, {resolution} m/px"
            )
            if time.monotonic() - clicked > 5.0:  # the map may have been busy loading the plan's detail
                row.click()
                clicked = time.monotonic()
            p.mouse.move(centre[0] + 100, centre[1])
            far = grid_readout(p)
            p.mouse.move(*centre)
            expect(p.get_by_test_id("grid-readout")).not_to_have_text(
                re.compile(re.escape(f"E {far[0]:.2f}"))
            )
            here = grid_readout(p)
            resolution = (far[0] - here[0]) / 100.0  # metres per pixel
            if (
                previous == here
                and abs(here[0] - gx) < 1.5 * resolution
                and abs(here[1] - gy) < 1.5 * resolution
            ):
                break
            previous = here
            p.wait_for_timeout(100)

        shift_px = (40, 30)
        p.mouse.move(*centre)
        p.mouse.down()
        p.mouse.move(centre[0] + shift_px[0], centre[1] + shift_px[1], steps=8)
        p.mouse.up()
        expect(p.get_by_test_id("grounding-message")).to_contain_text("moved the grounding")
        x, y = stored(grounding_id)
        assert abs(x - (gx + shift_px[0] * resolution)) < 2 * resolution, (x, gx, resolution)
        # screen y points down, northing up
        assert abs(y - (gy - shift_px[1] * resolution)) < 2 * resolution, (y, gy, resolution)
        screenshot(p, "ui_grounding_drag")

        p.get_by_test_id("undo").click()
        expect(p.get_by_test_id("grounding-message")).to_contain_text("undone")
        assert stored(grounding_id) == (gx, gy)
        p.get_by_test_id("redo").click()
        expect(p.get_by_test_id("grounding-message")).to_contain_text("redone")
        assert stored(grounding_id) == (x, y)
        p.keyboard.press("u")
        expect(p.get_by_test_id("redo")).to_be_enabled()
        assert stored(grounding_id) == (gx, gy)
        assert page.errors == []

    def test_disable_a_grounding_filter_by_drive_and_read_the_summary(
        self, server: Server, page: PageWithLog
    ) -> None:
        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-grounding").click()
        expect(p.get_by_test_id("residual-summary-all")).to_be_visible()
        first = groundings(server)[0]
        box = p.get_by_test_id(f"enable-grounding-{first['id']}")
        expect(box).to_be_checked()
        box.click()
        expect(p.get_by_test_id("grounding-message")).to_contain_text("left out of the next build")
        expect(box).not_to_be_checked()
        assert next(g for g in groundings(server) if g["id"] == first["id"])["enabled"] is False
        box.click()
        expect(box).to_be_checked()
        assert all(g["enabled"] for g in groundings(server))
        # RMS, mean and max of the build's residuals, overall and per drive (n, RMS, mean, max in metres)
        residuals = server.api("GET", "/api/sites/1/maps/1/residuals").json()

        def summary_cells(distances: list[float]) -> list[str]:
            rms = math.sqrt(sum(d * d for d in distances) / len(distances))
            mean = sum(distances) / len(distances)
            return [str(len(distances)), f"{rms:.2f}", f"{mean:.2f}", f"{max(distances):.2f}"]

        overall = p.get_by_test_id("residual-summary-all").locator("td")
        expect(overall.nth(1)).to_have_text(summary_cells([r["distance_m"] for r in residuals])[0])
        assert overall.all_inner_texts()[1:] == summary_cells([r["distance_m"] for r in residuals])
        p.get_by_test_id("grounding-drive-filter").select_option(str(first["drive_id"]))
        rows = p.get_by_test_id("groundings-table").locator("tbody tr")
        expect(rows).to_have_count(sum(g["drive_id"] == first["drive_id"] for g in groundings(server)))
        line = p.get_by_test_id(f"residual-summary-{first['drive']}")
        expect(line).to_be_visible()
        of_drive = [r["distance_m"] for r in residuals if r["drive"] == first["drive"]]
        assert line.locator("td").all_inner_texts() == [first["drive"], *summary_cells(of_drive)]
        assert page.errors == []

    def test_a_second_build_is_refused_and_each_preset_is_explained(
        self, server: Server, page: PageWithLog
    ) -> None:
        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-grounding").click()
        preset, explained = p.get_by_test_id("build-preset"), p.get_by_test_id("build-preset-explanation")
        expect(preset).to_have_value("paper")
        expect(explained).to_contain_text("the full loop-closure search")
        preset.select_option("fast")
        expect(explained).to_contain_text("far fewer loop closures")
        # the panel has looked for a build under way and found none; one queued now is met only by the click
        expect(p.get_by_test_id("build-map")).to_have_attribute("data-looked", "yes")
        queued = server.api("POST", "/api/sites/1/maps", json={"preset": "fast"})  # no worker: stays queued
        assert queued.status_code == 202, queued.text
        job = p.get_by_test_id("build-job")
        try:
            p.get_by_test_id("build-map").click()
            expect(p.get_by_test_id("build-refused")).to_contain_text(
                f"already building its map (job {queued.json()['id']}, queued)"
            )
            expect(job).to_have_attribute("data-status", "queued")  # the build under way is shown instead
            expect(job).to_contain_text(f"job {queued.json()['id']} (fast): queued: waiting for a worker")
            expect(p.get_by_test_id("build-map")).to_be_disabled()
            screenshot(p, "ui_build_presets")
            p.reload()  # a panel opened later shows it too
            expect(job).to_have_attribute("data-status", "queued")
        finally:
            server.api("POST", f"/api/jobs/{queued.json()['id']}/cancel")
        expect(job).to_have_attribute("data-status", "cancelled")
        expect(p.get_by_test_id("build-map")).to_be_enabled()
        assert [e for e in page.errors if "409 (Conflict)" not in e] == []  # the browser logs the refusal

    def test_a_row_opens_its_keyframe_any_frame_is_reached_and_the_large_view_zooms(
        self, server: Server, page: PageWithLog
    ) -> None:
        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-grounding").click()
        expect(p.get_by_test_id("map")).to_have_attribute("data-ready", "yes")
        last = groundings(server)[-1]
        p.get_by_test_id(f"grounding-row-{last['id']}").locator("td").nth(1).click()
        selected = p.get_by_test_id("selected-frame")
        expect(selected).to_have_attribute("data-frame", str(last["frame"]))
        expect(p.get_by_test_id("drive-select")).to_have_value(str(last["drive_id"]))
        # the residual arrows: to the keyframe's pose, then ten times as long
        residuals = server.api("GET", "/api/sites/1/maps/1/residuals").json()
        longest = max(r["distance_m"] for r in residuals)
        assert longest > 0.01, residuals
        wait_for_number(p, "map", "data-longest-arrow-m", longest)
        p.get_by_test_id("residual-exaggeration").select_option("10")
        wait_for_number(p, "map", "data-longest-arrow-m", 10 * longest)

        # any frame, not only the strip's keyframes; the strip turns to the keyframe before it
        p.get_by_test_id("goto-frame").fill("13")
        p.get_by_test_id("goto-frame").press("Enter")
        expect(selected).to_have_attribute("data-frame", "13")
        expect(p.get_by_test_id("frame-slider")).to_have_value("13")
        expect(p.get_by_test_id("keyframe-10")).to_be_in_viewport()
        expect(p.get_by_test_id("place-button")).to_be_visible()  # it can be grounded
        p.get_by_test_id("goto-frame").fill("999999")
        p.get_by_test_id("goto-frame-button").click()
        expect(p.get_by_test_id("goto-frame-error")).to_contain_text("the drive has frames 0 to")
        p.evaluate("document.activeElement.blur()")
        p.keyboard.press("ArrowRight")  # from a frame between keyframes to the next keyframe
        expect(selected).to_have_attribute("data-frame", "20")
        expect(p.get_by_test_id("keyframe-20")).to_have_class(re.compile("selected"))

        # the large view: at least 640 px wide with the plan beside it; zoom, fit, close
        p.get_by_test_id("frame-large").click()
        view = p.get_by_test_id("frame-view")
        expect(view).to_have_attribute("data-frame", "20")
        box, plan = view.bounding_box(), p.get_by_test_id("map").bounding_box()
        assert box is not None and plan is not None
        assert box["width"] >= 640 and plan["x"] >= box["x"] + box["width"] - 1 and plan["width"] > 200
        p.get_by_test_id("frame-zoom-in").click()
        expect(view).to_have_attribute("data-scale", "1.50")
        p.get_by_test_id("frame-view").locator(".frameview-box").hover()
        p.mouse.wheel(0, -100)
        expect(view).to_have_attribute("data-scale", "1.88")
        # a drag pans the zoomed image by as much as the pointer moved
        expect(view).to_have_attribute("data-shift", re.compile(r"^-\d+,-\d+$"))
        x0, y0 = (int(v) for v in (view.get_attribute("data-shift") or "").split(","))
        image = view.locator(".frameview-box").bounding_box()
        assert image is not None
        centre = (image["x"] + image["width"] / 2, image["y"] + image["height"] / 2)
        p.mouse.move(*centre)
        p.mouse.down()
        p.mouse.move(centre[0] + 30, centre[1] + 20, steps=5)
        p.mouse.up()
        expect(view).to_have_attribute("data-shift", f"{x0 + 30},{y0 + 20}")
        p.get_by_test_id("frame-fit").click()
        expect(view).to_have_attribute("data-scale", "1.00")
        p.get_by_test_id("frame-view-close").click()
        expect(view).to_have_count(0)
        assert page.errors == []

    def test_build_a_new_version_and_compare_it_with_the_old_as_an_overlay(
        self, server: Server, page: PageWithLog, worker: object
    ) -> None:
        # a grounding 30 m off its keyframe, left out of the build from its row: it changes nothing
        first = groundings(server)[0]
        taken = {g["frame"] for g in groundings(server) if g["drive_id"] == first["drive_id"]}
        stray = server.api(
            "POST",
            f"/api/drives/{first['drive_id']}/groundings",
            json={"frame": min(set(range(5, 100)) - taken), "x": first["x_m"] + 30.0, "y": first["y_m"]},
        )
        assert stray.status_code == 201, stray.text
        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-grounding").click()
        expect(p.get_by_test_id("map-version")).to_have_text("map v1")
        expect(p.get_by_test_id("compare-panel")).to_have_count(0)  # one version: nothing to compare
        box = p.get_by_test_id(f"enable-grounding-{stray.json()['id']}")
        box.click()  # the box shows the server's state once the PATCH is answered
        expect(p.get_by_test_id("grounding-message")).to_contain_text("left out of the next build")
        expect(box).not_to_be_checked()
        p.get_by_test_id("build-preset").select_option("fast")
        p.get_by_test_id("build-map").click()
        job = p.get_by_test_id("build-job")
        expect(job).to_have_attribute("data-preset", "fast")
        expect(job).to_have_attribute("data-status", "succeeded", timeout=BUILD_DEADLINE_MS)
        expect(job).to_have_attribute("data-progress", "1.000")
        expect(p.get_by_test_id("map-version")).to_have_text("map v2")
        used = server.api("GET", "/api/sites/1/maps/2/residuals").json()
        assert stray.json()["id"] not in {r["grounding_id"] for r in used}
        assert server.api("GET", "/api/sites/1/maps/compare", params={"a": 1, "b": 2}).json()["max_m"] < 0.01
        assert server.api("DELETE", f"/api/groundings/{stray.json()['id']}").status_code == 204

        p.get_by_test_id("toggle-compare").check()
        expect(p.get_by_test_id("compare-a")).to_have_value("1")
        expect(p.get_by_test_id("compare-b")).to_have_value("2")
        summary = p.get_by_test_id("compare-summary")
        expect(summary).to_have_attribute("data-state", "shown")
        compared = server.api("GET", "/api/sites/1/maps/compare", params={"a": 1, "b": 2}).json()
        expect(summary).to_have_attribute("data-a", "1")
        expect(summary).to_have_attribute("data-b", "2")
        expect(summary).to_have_attribute("data-frames", str(compared["frames"]))
        assert compared["frames"] > 0
        expect(summary).to_contain_text(f"max {compared['max_m']:.2f} m")
        screenshot(p, "ui_compare")

        p.get_by_test_id("compare-a").select_option("2")  # a version against itself moved nowhere
        expect(summary).to_have_attribute("data-a", "2")
        expect(summary).to_contain_text("max 0.00 m")
        p.get_by_test_id("toggle-compare").uncheck()
        expect(summary).to_have_count(0)

        # v2 reused every drive's kept odometry; "full rebuild" prepares every segment again
        reused = server.api("GET", "/api/sites/1/maps/2").json()["stats"]
        assert reused["segments_reused"] > 0 and reused["segments_prepared"] == 0, reused
        p.get_by_test_id("build-full").check()
        p.evaluate(WATCH_BUILD_JOB)
        p.get_by_test_id("build-map").click()
        expect(p.get_by_test_id("map-version")).to_have_text("map v3", timeout=BUILD_DEADLINE_MS)
        full = server.api("GET", "/api/sites/1/maps/3").json()["stats"]
        assert full["segments_reused"] == 0 and full["segments_prepared"] == reused["segments_reused"], full
        # the progress shown is the whole build's: it never goes back (a stage's restart at 0 % included),
        # and once under way it says about how long is left
        lines: list[list[str]] = p.evaluate("window.buildJobShown")
        job_of = [int(m.group(1)) if (m := re.search(r"job (\d+) ", text)) else -1 for _, text in lines]
        shown = [line for line, job_id in zip(lines, job_of, strict=True) if job_id == max(job_of)]
        progress = [float(value) for value, _ in shown]
        assert progress == sorted(progress) and any(0 < f < 1 for f in progress), shown
        assert progress[-1] == 1.0, shown
        assert any(re.search(r"\d+% · .+ · about .+ left", text) for _, text in shown), shown
        assert page.errors == []


class TestAdmin:
    def test_create_a_vehicle_shows_its_token_once(self, server: Server, page: PageWithLog) -> None:
        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-admin").click()
        p.get_by_test_id("new-vehicle-name").fill("truck-7")
        p.get_by_role("button", name="Add vehicle").click()
        token = p.get_by_test_id("vehicle-token").locator(".token")
        expect(token).to_contain_text("dmv_")
        expect(p.get_by_test_id("admin-vehicle-truck-7")).to_be_visible()
        assert any(v["name"] == "truck-7" for v in server.api("GET", "/api/vehicles").json())
        screenshot(p, "ui_admin")
        p.get_by_role("button", name="Done").click()
        expect(p.get_by_test_id("vehicle-token")).to_have_count(0)
        assert page.errors == []

    def test_copy_a_token_see_when_each_vehicle_was_last_seen_and_upload_a_plan_with_progress(
        self, server: Server, page: PageWithLog, tiny_site_dir: Path, tmp_path: Path
    ) -> None:
        site = server.api("POST", "/api/sites", json={"name": "upload-bay"})
        assert site.status_code == 201, site.text
        p = page.page
        p.context.grant_permissions(["clipboard-read", "clipboard-write"])
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-admin").click()

        p.get_by_test_id("new-vehicle-name").fill("loader-2")
        p.get_by_role("button", name="Add vehicle").click()
        token = p.get_by_test_id("vehicle-token").locator(".token").inner_text()
        p.get_by_test_id("copy-token").click()
        expect(p.get_by_test_id("copy-token-state")).to_have_text("copied")
        assert p.evaluate("navigator.clipboard.readText()") == token
        expect(p.get_by_test_id("admin-last-seen-loader-2")).to_have_text("never")

        # the plan goes to the chosen site, its progress shown; a bad drive zip is refused with the reason
        p.get_by_test_id("upload-site").select_option(str(site.json()["id"]))
        p.get_by_test_id("upload-plan-file").set_input_files(tiny_site_dir / "survey.dxf")
        p.get_by_test_id("upload-plan-send").click()
        plan = p.get_by_test_id("upload-plan")
        expect(plan).to_have_attribute("data-state", "done")
        expect(plan).to_contain_text("survey.dxf stored")
        plans = server.api("GET", f"/api/sites/{site.json()['id']}/survey").json()
        assert [m["filename"] for m in plans] == ["survey.dxf"]
        not_zip = tmp_path / "drive.zip"
        not_zip.write_bytes(b"not a zip file")
        p.get_by_test_id("upload-zip-file").set_input_files(not_zip)
        p.get_by_test_id("upload-zip-send").click()
        refused = p.get_by_test_id("upload-zip")
        expect(refused).to_have_attribute("data-state", "refused")
        expect(refused).to_contain_text("zip")
        # a drive folder's zip: its progress in megabytes, then the job that imports it
        drive_zip = tmp_path / "map-02.zip"
        drive_zip.write_bytes(zip_folder(tiny_site_dir / "drives" / "map-02"))
        megabytes = f"{drive_zip.stat().st_size / 1e6:.1f}"
        p.get_by_test_id("upload-zip-file").set_input_files(drive_zip)
        p.evaluate(WATCH_UPLOAD, "upload-zip")
        p.get_by_test_id("upload-zip-send").click()
        expect(refused).to_have_attribute("data-state", "done")
        expect(refused).to_contain_text(re.compile(r"uploaded; imported by job \d+ \(queued\)"))
        shown: list[list[str]] = p.evaluate("window.uploadShown")
        sending = [text for state, text in shown if state == "sending"]
        assert any(re.fullmatch(rf"[\d.]+ of {megabytes} MB \(\d+%\)", t) for t in sending), shown
        job_id = int(re.findall(r"job (\d+)", refused.inner_text())[0])
        job = server.api("GET", f"/api/jobs/{job_id}").json()
        assert job["status"] == "queued" and job["site_id"] == site.json()["id"], job
        assert server.api("POST", f"/api/jobs/{job_id}/cancel").status_code == 200
        p.get_by_test_id("upload-video-send").click()  # nothing chosen: said before anything is sent
        expect(p.get_by_test_id("upload-video")).to_contain_text("choose a video file")
        video, calibration = tmp_path / "run-9.mp4", tmp_path / "camera.json"
        video.write_bytes(b"\0" * 200_000)
        calibration.write_text("[1, 2]")
        p.get_by_test_id("upload-video-file").set_input_files(video)
        p.get_by_test_id("upload-video-calibration").set_input_files(calibration)
        p.get_by_test_id("upload-video-send").click()  # sent, and the server's reason shown
        expect(p.get_by_test_id("upload-video")).to_have_attribute("data-state", "refused")
        expect(p.get_by_test_id("upload-video")).to_contain_text("calibration must be a JSON object")
        screenshot(p, "ui_uploads")
        # a clip of the drive's camera with that camera's calibration: sent, then the job that imports it
        folder = tiny_site_dir / "drives" / "map-02"
        camera = json.loads((folder / "drive.json").read_text())["camera"]
        clip = tmp_path / "run-10.avi"
        writer = cv2.VideoWriter(
            str(clip), cv2.VideoWriter_fourcc(*"MJPG"), 5.0, (camera["width"], camera["height"])
        )
        for png in sorted((folder / "frames").glob("*.png"))[:6]:
            writer.write(cv2.imread(str(png)))
        writer.release()
        calibration.write_text(json.dumps({"camera": camera}))
        p.get_by_test_id("upload-video-file").set_input_files(clip)
        p.get_by_test_id("upload-video-calibration").set_input_files(calibration)
        p.get_by_test_id("upload-video-send").click()
        sent = p.get_by_test_id("upload-video")
        expect(sent).to_have_attribute("data-state", "done")
        expect(sent).to_contain_text(re.compile(r"uploaded; imported by job \d+ \(queued\)"))
        video_job = int(re.findall(r"job (\d+)", sent.inner_text())[0])
        job = server.api("GET", f"/api/jobs/{video_job}").json()
        facts = (job["kind"], job["args"]["format"], job["args"]["name"], job["status"], job["site_id"])
        assert facts == ("drive.import", "video", "run-10", "queued", site.json()["id"]), job
        assert server.api("POST", f"/api/jobs/{job['id']}/cancel").status_code == 200
        # the browser logs the two refused requests, and nothing else
        assert [e for e in page.errors if "Failed to load resource" not in e] == [], page.errors

    def test_disable_a_user_refuses_their_login_and_enable_lets_them_back(
        self, server: Server, page: PageWithLog
    ) -> None:
        password = make_user(server, "shift-boss", "viewer")
        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-admin").click()
        row = p.get_by_test_id("user-row-shift-boss")
        row.get_by_test_id("user-toggle-shift-boss").click()
        expect(row).to_contain_text("disabled")
        refused = server.api("POST", "/api/auth/login", json={"username": "shift-boss", "password": password})
        assert refused.status_code == 403 and "disabled" in refused.json()["detail"]
        row.get_by_test_id("user-toggle-shift-boss").click()
        expect(row).to_contain_text("active")
        login = server.api("POST", "/api/auth/login", json={"username": "shift-boss", "password": password})
        assert login.status_code == 200
        assert page.errors == []

    def test_deletes_ask_first_and_a_new_row_moves_no_button_under_the_pointer(
        self, server: Server, page: PageWithLog
    ) -> None:
        make_user(server, "temp-user", "viewer")
        made = server.api("POST", "/api/vehicles", json={"name": "doomed-1", "site_id": 1})
        assert made.status_code == 201, made.text
        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-admin").click()
        expect(p.get_by_test_id("user-row-temp-user")).to_be_visible()

        def user_names() -> list[str]:
            return [u["username"] for u in server.api("GET", "/api/users").json()]

        # Add: the new row appears, the button stays where the pointer is
        add = p.get_by_test_id("add-user")
        p.get_by_test_id("new-user-name").fill("new-hand")
        p.get_by_test_id("new-user-password").fill("new-hand-password")
        before = add.bounding_box()
        assert before is not None
        add.click()
        expect(p.get_by_test_id("user-row-new-hand")).to_be_visible()
        assert add.bounding_box() == before
        under = p.evaluate(
            "([x, y]) => document.elementFromPoint(x, y)?.closest('button')?.dataset.testid ?? ''",
            [before["x"] + before["width"] / 2, before["y"] + before["height"] / 2],
        )
        assert under == "add-user", under

        # Delete asks; Cancel (or Escape) keeps the user, the confirmation deletes
        p.get_by_test_id("user-delete-temp-user").click()
        dialog = p.get_by_test_id("confirm-dialog")
        expect(dialog).to_contain_text("Delete user temp-user?")
        expect(p.get_by_test_id("confirm-cancel")).to_be_focused()  # Enter does not delete
        p.get_by_test_id("confirm-cancel").click()
        expect(dialog).to_have_count(0)
        p.get_by_test_id("user-delete-temp-user").click()
        p.keyboard.press("Escape")
        expect(dialog).to_have_count(0)
        assert "temp-user" in user_names()
        p.get_by_test_id("user-delete-temp-user").click()
        p.get_by_test_id("confirm-ok").click()
        expect(p.get_by_test_id("user-row-temp-user")).to_have_count(0)
        assert "temp-user" not in user_names()

        # a password reset: the user logs in with the new one
        p.get_by_test_id("user-reset-new-hand").click()
        p.get_by_test_id("reset-password").fill("fresh-password-1")
        with p.expect_response(lambda r: r.request.method == "PATCH" and "/api/users/" in r.url) as patched:
            p.get_by_test_id("reset-ok").click()
        assert patched.value.status == 200
        login = server.api(
            "POST", "/api/auth/login", json={"username": "new-hand", "password": "fresh-password-1"}
        )
        assert login.status_code == 200, login.text

        # vehicles too
        p.get_by_test_id("vehicle-delete-doomed-1").click()
        expect(dialog).to_contain_text("Delete vehicle doomed-1?")
        p.get_by_test_id("confirm-ok").click()
        expect(p.get_by_test_id("admin-vehicle-doomed-1")).to_have_count(0)
        assert "doomed-1" not in [v["name"] for v in server.api("GET", "/api/vehicles").json()]
        assert page.errors == []

    def test_the_last_admin_cannot_be_deleted_demoted_or_disabled(
        self, server: Server, page: PageWithLog
    ) -> None:
        p = page.page
        log_in(p, server, "admin", ADMIN_PASSWORD)
        p.get_by_test_id("nav-admin").click()
        delete, role = p.get_by_test_id("user-delete-admin"), p.get_by_test_id("user-role-admin")
        expect(delete).to_be_disabled()
        expect(delete).to_have_attribute("title", "you cannot delete your own account")
        expect(role).to_be_disabled()
        expect(role).to_have_attribute("title", re.compile("admin is the last active admin"))
        expect(p.get_by_test_id("user-toggle-admin")).to_be_disabled()

        # with a second admin the first may be demoted, and the second deleted
        p.get_by_test_id("new-user-name").fill("deputy")
        p.get_by_test_id("new-user-password").fill("deputy-password")
        p.get_by_test_id("new-user-role").select_option("admin")
        p.get_by_test_id("add-user").click()
        expect(p.get_by_test_id("user-role-deputy")).to_have_value("admin")
        expect(role).to_be_enabled()
        expect(p.get_by_test_id("user-delete-deputy")).to_be_enabled()
        expect(delete).to_be_disabled()  # never yourself

        # the deputy demoted: the first is the last admin again
        p.get_by_test_id("user-role-deputy").select_option("surveyor")
        expect(role).to_be_disabled()
        deputy = next(u for u in server.api("GET", "/api/users").json() if u["username"] == "deputy")
        assert deputy["role"] == "surveyor"

        # the server refuses the same, and says why
        me = server.api("GET", "/api/auth/me").json()
        demote = server.api("PATCH", f"/api/users/{me['id']}", json={"role": "viewer"})
        assert demote.status_code == 409 and "last active admin" in demote.json()["detail"], demote.text
        removed = server.api("DELETE", f"/api/users/{me['id']}")
        assert removed.status_code == 409 and "your own account" in removed.json()["detail"], removed.text
        assert page.errors == []


PAGES = ("survey", "monitor", "grounding", "cameras", "admin")
TABLET = {"width": 390, "height": 844}


def sideways_overflow_px(page: Page) -> float:
    """How far the page reaches beyond the window sideways (0: nothing to scroll to)."""
    over: float = page.evaluate(
        "() => Math.max(document.documentElement.scrollWidth, document.body.scrollWidth)"
        " - document.documentElement.clientWidth"
    )
    return over


class TestLayout:
    def test_a_tablet_gets_a_menu_a_full_width_map_and_a_pull_up_panel_and_nothing_overflows(
        self, server: Server, page: PageWithLog
    ) -> None:
        p = page.page
        p.set_viewport_size(TABLET)
        log_in(p, server, "admin", ADMIN_PASSWORD)
        menu = p.get_by_test_id("menu-toggle")
        expect(menu).to_be_visible()
        expect(p.get_by_test_id("nav-monitor")).to_be_hidden()  # the header is folded into the menu
        menu.click()
        p.get_by_test_id("nav-monitor").click()
        expect(p.get_by_test_id("nav-monitor")).to_be_hidden()  # a choice closes the menu
        expect(p.get_by_test_id("vehicle-list")).to_be_attached()
        plan = p.get_by_test_id("map").bounding_box()
        assert plan is not None and plan["width"] >= TABLET["width"] - 1, plan

        side, handle = p.locator("aside.side"), p.get_by_test_id("panel-handle")
        closed = side.bounding_box()
        assert closed is not None and closed["width"] >= TABLET["width"] - 1
        handle.click()  # pull the panel up: vehicles and events
        expect(handle).to_have_attribute("aria-expanded", "true")
        expect(p.get_by_test_id("events-panel")).to_be_in_viewport()
        opened = side.bounding_box()
        assert opened is not None and opened["height"] > closed["height"] * 2, (closed, opened)
        screenshot(p, "ui_tablet")

        for name in PAGES:
            menu.click()
            p.get_by_test_id(f"nav-{name}").click()
            expect(p.get_by_test_id(f"nav-{name}")).to_be_hidden()
            assert sideways_overflow_px(p) <= 0, f"{name} overflows sideways at 390 px"
        for width in (1366, 1440):
            p.set_viewport_size({"width": width, "height": 800})
            expect(menu).to_be_hidden()
            for name in PAGES:
                p.get_by_test_id(f"nav-{name}").click()
                expect(p.get_by_test_id(f"nav-{name}")).to_have_class("active")
                assert sideways_overflow_px(p) <= 0, f"{name} overflows sideways at {width} px"
        assert page.errors == []
