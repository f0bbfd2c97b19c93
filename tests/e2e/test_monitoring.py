"""Live monitoring in the browser: replaying a time range of a vehicle's history (speed, scrubber, follow),
the camera-obscured status, alert and event, the vehicle's latest frame, each vehicle in its own colour (swatch
and trail, the trail cut at a jump) and following it on the map, placing a vehicle's known start on the plan
and its trail along the tunnels, a lost vehicle's event ending "found again", an event beeping for the user
who turned the sound on, acknowledged on one user's screen and showing so on another's, ending ("back") when
its vehicle reports again, filtered and exported as CSV; against a real ``driftmap serve`` (fixtures of
``conftest.py``).

Every wait polls the DOM or the API up to a deadline (Playwright's ``expect``); nothing sleeps for a fixed time.
"""

from __future__ import annotations

import csv
import io
import itertools
import json
import math
import re
import time
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from playwright.sync_api import Browser, Locator, Page, Request, expect

from driftmap.formats.frame_images import decode_gray, encode_png
from driftmap.sim.obscurants import LEVELS, apply_level
from tests.api.access_helpers import localisation_drive, recorded_frames
from tests.e2e.conftest import (
    ADMIN_PASSWORD,
    STALE_AFTER_S,
    VIEWPORT_H,
    VIEWPORT_W,
    PageWithLog,
    Server,
    add_user,
    screenshot,
)
from tests.e2e.map_helpers import distance_to_lines, inside_walls, layer_lines, pixel_of, plain_map_at

pytestmark = pytest.mark.slow  # a real server and a browser

DEADLINE_S = 60.0
# the vehicles of the latest-frame test drive on from these frames of the drive (after its standing start)
TRAIL_FROM, TRAIL_APART, TRAIL_STRIDE = 40, 100, 4
FRAME_PERIOD_S = 0.1
LOST_WITHIN_FRAMES = 20  # frames of noise after which the localiser has said lost (it takes three)
REPLAY_FRAMES = 40
START_FRAMES = 100  # ten seconds of the drive: it stands for one, then drives about ten metres
CLICK_TOLERANCE_M = 1.0  # a click lands within a pixel or two of the aimed point (about 0.3 m/px when fitted)
JUMP_SLACK_M, JUMP_SPEED_MPS = 5.0, 10.0  # a trail's jump (frontend/src/lib/trail.ts)
CENTRELINE_TOLERANCE_M = (
    2.0  # the drives keep within 1.5 m of the surveyed centreline; the walls are ~3 m off
)


def log_in(page: Page, server: Server, username: str = "admin", password: str = ADMIN_PASSWORD) -> None:
    page.goto(f"{server.base}/")
    page.fill("#username", username)
    page.fill("#password", password)
    page.click("button[type=submit]")
    expect(page.get_by_test_id("whoami")).to_contain_text(username)


class Vehicle:
    """A vehicle registered through the API that posts frames with its own token."""

    def __init__(self, server: Server, name: str) -> None:
        made = server.api("POST", "/api/vehicles", json={"name": name, "site_id": 1})
        assert made.status_code in (200, 201), made.text
        self.server, self.id, self.token = server, made.json()["id"], made.json()["token"]

    def post(self, t: float, data: bytes) -> dict:  # type: ignore[type-arg]
        answer = self.server.api(
            "POST",
            f"/api/vehicles/{self.id}/frames",
            token=self.token,
            params={"t": t},
            content=data,
            headers={"Content-Type": "image/png"},
        )
        assert answer.status_code == 200, answer.text
        body: dict = answer.json()  # type: ignore[type-arg]
        return body


def _number(page: Page, attribute: str) -> float:
    value = page.get_by_test_id("replay-panel").get_attribute(attribute)
    assert value not in (None, ""), attribute
    return float(value)  # type: ignore[arg-type]


class TestReplay:
    def test_replay_a_range_with_speed_scrubber_and_follow(
        self, server: Server, page: PageWithLog, tiny_site_dir: Path
    ) -> None:
        frames = recorded_frames(localisation_drive(tiny_site_dir), REPLAY_FRAMES)
        vehicle = Vehicle(server, "replay-1")
        t0 = round(time.time()) - 60.0  # a wall-clock vehicle time, as `driftmap replay` posts
        answers = [vehicle.post(t0 + FRAME_PERIOD_S * i, f.data) for i, f in enumerate(frames)]
        assert all(a["status"] == "processed" for a in answers)
        history = server.api("GET", f"/api/vehicles/{vehicle.id}/positions").json()
        start, end = history[0]["t"], history[-1]["t"]

        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-monitor").click()
        p.get_by_test_id("vehicle-row-replay-1").click()
        expect(p.get_by_test_id("vehicle-details")).to_contain_text("replay-1")
        # the range defaults to the vehicle's last five minutes, written as local clock times
        expect(p.get_by_test_id("replay-to")).to_have_value(re.compile(r"^\d{4}-\d\d-\d\d \d\d:\d\d:\d\d$"))
        p.get_by_test_id("replay-load").click()
        panel = p.get_by_test_id("replay-panel")
        expect(panel).to_have_attribute("data-count", str(REPLAY_FRAMES))
        expect(panel).to_have_attribute("data-state", "paused")
        assert _number(p, "data-t") == round(start, 2)

        # play at 2x: the 3.9 s of history takes about 2 s, then the replay stops at its end
        p.get_by_test_id("replay-speed").select_option("2")
        played = time.monotonic()
        p.get_by_test_id("replay-play").click()
        expect(panel).to_have_attribute("data-state", "playing")
        expect(p.get_by_test_id("replay-play")).to_have_text("Pause")
        expect(panel).to_have_attribute("data-state", "paused", timeout=30_000)
        took = time.monotonic() - played
        assert took >= 0.9 * (end - start) / 2, took
        assert _number(p, "data-t") == round(end, 2)
        assert _number(p, "data-index") == REPLAY_FRAMES - 1

        # scrub to the middle: the time, the index and the readout follow
        middle = start + 0.5 * (end - start)
        p.get_by_test_id("replay-scrubber").fill(str(middle))
        expect(panel).to_have_attribute("data-t", f"{middle:.2f}")
        index = int(_number(p, "data-index"))
        assert history[index]["t"] <= middle < history[index + 1]["t"]
        expect(p.get_by_test_id("replay-time")).to_contain_text(f"{REPLAY_FRAMES} positions")

        # follow: the map centres on the replayed vehicle and stays there while it plays
        p.get_by_test_id("replay-follow").check()
        expect(panel).to_have_attribute("data-follow-offset", re.compile(r"^0\.0\d$"))
        p.get_by_test_id("replay-speed").select_option("1")
        p.get_by_test_id("replay-play").click()
        expect(panel).to_have_attribute("data-state", "playing")
        screenshot(p, "ui_replay")
        expect(panel).to_have_attribute("data-state", "paused", timeout=30_000)
        assert float(panel.get_attribute("data-follow-offset") or "nan") < 0.1

        p.get_by_test_id("replay-close").click()
        expect(panel).to_have_count(0)
        assert page.errors == []

    def test_a_bad_time_and_an_empty_range_are_explained(
        self, server: Server, page: PageWithLog, tiny_site_dir: Path
    ) -> None:
        frames = recorded_frames(localisation_drive(tiny_site_dir), 3)
        vehicle = Vehicle(server, "replay-2")
        for i, f in enumerate(frames):  # a drive clock in seconds: the inputs show elapsed drive time
            vehicle.post(500.0 + FRAME_PERIOD_S * i, f.data)
        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-monitor").click()
        p.get_by_test_id("vehicle-row-replay-2").click()
        expect(p.get_by_test_id("replay-to")).to_have_value("+0:08:20.2")
        p.get_by_test_id("replay-from").fill("yesterday")
        p.get_by_test_id("replay-load").click()
        expect(p.get_by_test_id("replay-error")).to_contain_text("Write times as")
        p.get_by_test_id("replay-from").fill("10")
        p.get_by_test_id("replay-to").fill("20")
        p.get_by_test_id("replay-load").click()
        expect(p.get_by_test_id("replay-error")).to_contain_text("No positions in that range")
        expect(p.get_by_test_id("replay-panel")).to_have_count(0)
        p.get_by_test_id("replay-last-5").click()
        p.get_by_test_id("replay-load").click()
        expect(p.get_by_test_id("replay-panel")).to_have_attribute("data-count", "3")
        assert page.errors == []


class TestObscuredCamera:
    def test_dust_on_the_lens_shows_camera_obscured_and_an_alert(
        self, server: Server, page: PageWithLog, tiny_site_dir: Path
    ) -> None:
        frames = recorded_frames(localisation_drive(tiny_site_dir), 30)
        rng = np.random.default_rng(9)
        dusty = [encode_png(apply_level(decode_gray(f.data), LEVELS["dust2"], rng)) for f in frames]
        vehicle = Vehicle(server, "dusty-1")
        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-monitor").click()
        expect(p.get_by_test_id("live-connection")).to_have_text("live")

        t = 1000.0
        for f in frames[:12]:  # clean, past the judgement's warm-up
            assert vehicle.post(t, f.data)["obscured"] is False
            t += FRAME_PERIOD_S
        row = p.get_by_test_id("vehicle-row-dusty-1")
        expect(row).not_to_have_attribute("data-status", "camera obscured")
        expect(p.get_by_test_id("obscured-alert")).to_have_count(0)

        deadline = time.monotonic() + DEADLINE_S
        i = 0
        while row.get_attribute("data-status") != "camera obscured":
            assert time.monotonic() < deadline, "no camera-obscured status"
            vehicle.post(t, dusty[i % len(dusty)])
            t += FRAME_PERIOD_S
            i += 1
        expect(row).to_contain_text("camera obscured")
        expect(p.get_by_test_id("obscured-alert")).to_contain_text("dusty-1 (dust)")
        row.click()
        expect(p.get_by_test_id("camera-check")).to_have_attribute("data-obscured", "yes")
        expect(p.get_by_test_id("camera-check")).to_contain_text("obscured (dust)")
        # the vehicle's latest frame is shown with it (the dust is visible in the picture)
        frame = p.get_by_test_id("latest-frame")
        expect(frame).to_be_visible()
        assert float(frame.get_attribute("data-t") or "nan") >= 1000.0
        assert frame.evaluate("img => img.naturalWidth") == 320
        screenshot(p, "ui_obscured")
        # the event log keeps it: open while the lens is dusty, ended ("camera clear") once it is clean again
        event = p.get_by_test_id("events-pending").locator('[data-vehicle="dusty-1"][data-kind="obscured"]')
        expect(event).to_have_attribute("data-open", "true")
        deadline = time.monotonic() + DEADLINE_S
        i = 0
        while row.get_attribute("data-status") == "camera obscured":
            assert time.monotonic() < deadline, "the camera never cleared"
            vehicle.post(t, frames[i % len(frames)].data)
            t += FRAME_PERIOD_S
            i += 1
        expect(event).to_have_attribute("data-open", "false")
        expect(event).to_contain_text(re.compile(r"camera clear \d\d:\d\d:\d\d"))
        expect(p.get_by_test_id("obscured-alert")).to_have_count(0)
        assert page.errors == []


class TestLatestFrame:
    def test_the_panel_shows_exactly_the_selected_vehicles_latest_frame(
        self, server: Server, page: PageWithLog, tiny_site_dir: Path
    ) -> None:
        frames = recorded_frames(localisation_drive(tiny_site_dir))
        names = ("cam-1", "cam-2", "cam-3")
        last_t = {}
        vehicles = {}
        for k, name in enumerate(names):  # each on its own clock, so a frame's time tells whose it is
            vehicle = vehicles[name] = Vehicle(server, name)
            for i in range(3):
                last_t[name] = 3000.0 + 100.0 * k + FRAME_PERIOD_S * i
                assert vehicle.post(last_t[name], frames[3 * k + i].data)["status"] == "processed"
        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-monitor").click()
        details = p.get_by_test_id("vehicle-details")
        for name in (*names, "cam-1", "cam-3", "cam-2"):
            p.get_by_test_id(f"vehicle-row-{name}").click()
            expect(details.locator("h3").first).to_contain_text(name)
            frame = details.get_by_test_id("latest-frame")
            expect(frame).to_have_attribute("data-vehicle", name)
            expect(details.locator("img")).to_have_count(1)
            expect(frame).to_have_attribute("data-t", re.compile(rf"^{re.escape(str(last_t[name]))}"))
            expect(details.get_by_test_id("latest-frame-caption")).to_contain_text(name)
            # one time format: a drive clock as elapsed drive time
            expect(details.get_by_test_id("latest-frame-caption")).to_contain_text(
                f"+0:{int(last_t[name]) // 60 % 60:02d}:"
            )
        # one colour per vehicle: its swatch in the list and the details, and its trail on the plan
        swatches = {
            n: _rgb(p.get_by_test_id(f"vehicle-row-{n}").get_by_test_id("vehicle-colour")) for n in names
        }
        assert len(set(swatches.values())) == len(names), swatches
        assert _rgb(details.get_by_test_id("vehicle-colour")) == swatches["cam-2"]
        for k, name in enumerate(names):  # then each drives on elsewhere, the page open: a trail each
            for i in range(1, 5):
                drove = frames[TRAIL_FROM + TRAIL_APART * k + TRAIL_STRIDE * i]
                seq = vehicles[name].post(last_t[name] + FRAME_PERIOD_S * i, drove.data)["seq"]
            expect(p.get_by_test_id(f"vehicle-row-{name}")).to_have_attribute("data-seq", str(seq))
        plan = p.get_by_test_id("map")
        expect(plan).to_have_attribute(
            "data-trail-colours", re.compile('^(?=.*"cam-1")(?=.*"cam-2")(?=.*"cam-3")')
        )
        trails = json.loads(plan.get_attribute("data-trail-colours") or "{}")
        assert {n: _channels(trails[n]) for n in names} == swatches, (trails, swatches)
        # each drove on from afar: the trail (the snapshot's last position, then the new ones) is cut at a jump
        seen = {n: server.api("GET", f"/api/vehicles/{vehicles[n].id}/positions").json()[2:] for n in names}
        pieces = {n: _trail_pieces(seen[n]) for n in names}
        assert max(pieces.values()) >= 2, f"no vehicle jumped: {seen}"

        def drawn() -> dict[str, int | None]:  # (the page also draws earlier tests' vehicles)
            every = json.loads(plan.get_attribute("data-trail-pieces") or "{}")
            return {n: every.get(n) for n in names}

        deadline = time.monotonic() + DEADLINE_S
        while drawn() != pieces:
            assert time.monotonic() < deadline, f"trail pieces drawn {drawn()}, expected {pieces}"
            p.wait_for_timeout(100)
        screenshot(p, "ui_monitoring_colours")
        # full size on a click, Escape closes it
        details.get_by_test_id("latest-frame").click()
        full = p.get_by_test_id("frame-full")
        expect(full).to_contain_text("cam-2")
        assert full.locator("img").evaluate("img => img.naturalWidth") == 320
        p.keyboard.press("Escape")
        expect(full).to_have_count(0)

        # follow: the map centres on the selected vehicle until the user drags the map
        follow = p.get_by_test_id("follow-toggle")
        follow.check()
        expect(plan).to_have_attribute("data-follow-offset", "0.00")
        box = plan.bounding_box()
        assert box is not None
        p.mouse.move(box["x"] + 0.5 * box["width"], box["y"] + 0.5 * box["height"])
        p.mouse.down()
        p.mouse.move(box["x"] + 0.3 * box["width"], box["y"] + 0.4 * box["height"], steps=5)
        p.mouse.up()
        expect(follow).not_to_be_checked()
        expect(plan).not_to_have_attribute("data-follow-offset", re.compile(".*"))

        assert page.errors == []


COUNT_BEEPS = """() => {
  document.body.dataset.beeps = "0";
  const start = OscillatorNode.prototype.start;
  OscillatorNode.prototype.start = function (...args) {
    document.body.dataset.beeps = String(Number(document.body.dataset.beeps) + 1);
    return start.apply(this, args);
  };
}"""
"""Counts the beeps the page plays (oscillators started) in ``body``'s ``data-beeps``."""


def _trail_pieces(positions: list[dict[str, Any]]) -> int:
    """How many pieces a trail through ``positions`` is cut into: a step further than 5 m plus 10 m/s times its
    time is a jump (``frontend/src/lib/trail.ts``)."""
    jumps = sum(
        math.hypot(b["x"] - a["x"], b["y"] - a["y"])
        > JUMP_SLACK_M + JUMP_SPEED_MPS * max(0.0, b["t"] - a["t"])
        for a, b in itertools.pairwise(positions)
    )
    return 1 + jumps


def _confidence_text(confidence: float) -> str:
    """The UI's percentage: rounded down, so the text and the band always agree."""
    return f"{min(100, max(0, math.floor(confidence * 100 + 1e-9)))} %"


def _channels(css: str) -> tuple[int, ...]:
    """The red, green and blue of a CSS ``rgb()`` or ``rgba()`` colour (alpha left out)."""
    return tuple(int(c) for c in re.findall(r"\d+", css)[:3])


def _rgb(swatch: Locator) -> tuple[int, ...]:
    """The colour a vehicle swatch shows."""
    return _channels(swatch.get_attribute("data-colour") or "")


def _band(position: dict[str, Any]) -> str:
    percent = math.floor(position["confidence"] * 100 + 1e-9)
    if position["lost"]:
        return "lost"
    return "confident" if percent >= 90 else "uncertain" if percent >= 50 else "doubtful"


def _speed_text(speed_mps: float | None) -> str:
    if speed_mps is None:
        return "—"
    text = f"{abs(speed_mps):.1f} m/s"
    return f"{text} reversing" if speed_mps < 0 and text != "0.0 m/s" else text


def _bearing_text(yaw: float | None) -> str:
    """The UI's heading: grid bearing clockwise from north with its compass point."""
    if yaw is None:
        return "—"
    degrees = round((90 - math.degrees(yaw)) % 360) % 360
    return f"{degrees:03d}° {['N', 'NE', 'E', 'SE', 'S', 'SW', 'W', 'NW'][round(degrees / 45) % 8]}"


class TestKnownStart:
    def test_place_a_start_on_the_plan_then_the_trail_follows_the_tunnels(
        self, server: Server, page: PageWithLog, tiny_site_dir: Path
    ) -> None:
        drive = localisation_drive(tiny_site_dir)
        frames = recorded_frames(drive, START_FRAMES + 10)
        vehicle = Vehicle(server, "start-1")
        camera = json.loads((drive / "drive.json").read_text())["camera"]  # its frames carry odometry
        assert server.api("PUT", f"/api/vehicles/{vehicle.id}/camera", json=camera).status_code == 200
        centreline, walls = layer_lines(server, "CENTRELINE"), layer_lines(server, "WALLS")
        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-monitor").click()
        expect(p.get_by_test_id("live-connection")).to_have_text("live")
        expect(p.get_by_test_id("map")).to_have_attribute("data-ready", "yes")
        expect(p.get_by_test_id("confidence-legend")).to_contain_text("confident")
        row = p.get_by_test_id("vehicle-row-start-1")
        row.click()
        expect(p.get_by_test_id("vehicle-details")).to_contain_text("No position yet")

        # aim at the drive's true position at its first frame whose pixel is plain map (no legend over it)
        first = next(i for i, f in enumerate(frames[:10]) if plain_map_at(p, *pixel_of(p, f.x, f.y)))
        aim = frames[first]
        assert distance_to_lines((aim.x, aim.y), centreline) < CENTRELINE_TOLERANCE_M  # a tunnel point
        px, py = pixel_of(p, aim.x, aim.y)
        starts: list[Any] = []  # the bodies of the start requests the page sent

        def on_request(request: Request) -> None:
            if request.method == "POST" and request.url.endswith(f"/api/vehicles/{vehicle.id}/start"):
                starts.append(request.post_data_json)

        p.on("request", on_request)

        # a click on the map outside the set-start mode sends nothing; Escape leaves the mode
        p.mouse.click(px, py)
        p.get_by_test_id("set-start-button").click()
        expect(p.get_by_test_id("set-start-hint")).to_be_visible()
        p.keyboard.press("Escape")
        expect(p.get_by_test_id("set-start")).to_have_attribute("data-placing", "no")
        p.mouse.click(px, py)

        # refused: the server's reason is shown and the mode stays for another click
        p.get_by_test_id("start-radius").fill("500")
        p.get_by_test_id("set-start-button").click()
        p.mouse.click(px, py)
        result = p.get_by_test_id("start-result")
        expect(result).to_have_attribute("data-state", "refused")
        expect(result).to_contain_text("radius_m")
        expect(p.get_by_test_id("set-start")).to_have_attribute("data-placing", "yes")
        assert len(starts) == 1, starts  # the stray clicks sent nothing

        p.get_by_test_id("start-radius").fill("10")
        p.mouse.click(px, py)
        expect(result).to_have_attribute("data-state", "accepted")
        expect(result).to_contain_text("Start set at")
        expect(p.get_by_test_id("set-start")).to_have_attribute("data-placing", "no")
        # the event log records it, acknowledged by whoever set it
        logged = p.get_by_test_id("events-acknowledged").locator(
            '[data-vehicle="start-1"][data-kind="start_known"]'
        )
        expect(logged).to_contain_text("known start set (radius 10 m)")
        expect(logged.get_by_test_id("event-acknowledged-by")).to_contain_text("admin")
        sent = starts[-1]
        assert sent["radius_m"] == 10
        # survey coordinates, the map's local origin added back: the aimed tunnel point within a pixel or two
        assert math.hypot(sent["x"] - aim.x, sent["y"] - aim.y) < CLICK_TOLERANCE_M, (sent, aim)

        # the vehicle drives on from there: its trail grows, every position on a tunnel
        for f in frames[first : first + START_FRAMES]:
            assert vehicle.post(f.t, f.data)["status"] == "processed"
        expect(row).to_have_attribute("data-trail", str(START_FRAMES))
        history = server.api("GET", f"/api/vehicles/{vehicle.id}/positions").json()
        assert len(history) == START_FRAMES
        points = [(h["x"], h["y"]) for h in history]
        # the trail's points and the middles of its segments: a trail cutting a corner through rock fails
        drawn = points + [((a[0] + b[0]) / 2, (a[1] + b[1]) / 2) for a, b in itertools.pairwise(points)]
        off = [(q, d) for q in drawn if (d := distance_to_lines(q, centreline)) > CENTRELINE_TOLERANCE_M]
        assert off == [], f"trail off the centreline: {off}"
        outside = [q for q in drawn if not inside_walls(q, walls)]
        assert outside == [], f"trail outside the tunnel walls: {outside}"
        moved = math.hypot(history[-1]["x"] - history[0]["x"], history[-1]["y"] - history[0]["y"])
        assert moved > 1.0, moved  # a trail, not one point

        # one confidence, shown the same way in the list and the details; motion as the server said it
        last = history[-1]
        expect(row).to_have_attribute("data-seq", str(last["seq"]))
        expect(row).to_have_attribute("data-band", _band(last))
        expect(row).to_contain_text(_confidence_text(last["confidence"]))
        expect(p.get_by_test_id("detail-confidence")).to_contain_text(_confidence_text(last["confidence"]))
        expect(p.get_by_test_id("detail-speed")).to_have_text(f"Speed{_speed_text(last['speed_mps'])}")
        expect(p.get_by_test_id("detail-heading")).to_contain_text(_bearing_text(last["yaw"]))
        badge = p.get_by_test_id("vehicle-details").get_by_test_id("appearance-only")
        expect(badge).to_have_count(0 if last["odometry"] else 1)
        screenshot(p, "ui_known_start")
        # the browser logs the refused start's answer (422), and nothing else
        assert [e for e in page.errors if not re.match(r"Failed to load resource: .* 422 ", e)] == []


class TestEvents:
    def test_a_lost_vehicle_raises_an_event_that_stays_after_it_is_found_again(
        self, server: Server, page: PageWithLog, tiny_site_dir: Path
    ) -> None:
        frames = recorded_frames(localisation_drive(tiny_site_dir), 30)
        shape = decode_gray(frames[0].data).shape
        noise = encode_png(np.random.default_rng(4).integers(0, 256, size=shape, dtype=np.uint8))
        vehicle = Vehicle(server, "lost-1")
        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-monitor").click()
        expect(p.get_by_test_id("live-connection")).to_have_text("live")
        t = 4000.0
        for f in frames[:10]:
            assert vehicle.post(t, f.data)["lost"] is False
            t += FRAME_PERIOD_S

        # frames that match nothing (a camera fed noise): the vehicle is lost, the alert and an open event show
        for _ in range(LOST_WITHIN_FRAMES):
            t += FRAME_PERIOD_S
            if vehicle.post(t, noise)["lost"]:
                break
        else:
            raise AssertionError(f"not lost after {LOST_WITHIN_FRAMES} noise frames")
        expect(p.get_by_test_id("lost-alert")).to_contain_text("lost-1")
        event = p.get_by_test_id("events-pending").locator('[data-vehicle="lost-1"][data-kind="lost"]')
        expect(event).to_have_attribute("data-open", "true")
        expect(event).to_contain_text("ongoing")

        # the drive's frames again: found again; the alert goes, the event ends and stays until acknowledged
        for f in frames[10:]:
            t += FRAME_PERIOD_S
            if not vehicle.post(t, f.data)["lost"]:
                break
        else:
            raise AssertionError("never found again")
        expect(p.get_by_test_id("lost-alert")).to_have_count(0)
        expect(event).to_have_attribute("data-open", "false")
        expect(event).to_contain_text(re.compile(r"found again \d\d:\d\d:\d\d"))
        expect(event).to_have_attribute("data-acknowledged", "false")
        stored = server.api("GET", "/api/events", params={"vehicle": vehicle.id, "kind": "lost"}).json()
        (lost,) = stored["items"]
        assert lost["ended_at"] is not None and lost["acknowledged_at"] is None, lost
        assert page.errors == []

    def test_an_event_acknowledged_by_one_user_shows_acknowledged_to_another(
        self, server: Server, page: PageWithLog, browser: Browser, tiny_site_dir: Path
    ) -> None:
        add_user(server.env, "watcher", "viewer", "e2e-watcher-password")
        silent, other = Vehicle(server, "silent-1"), Vehicle(server, "quiet-2")  # quiet-2 never reports
        admin = page.page
        log_in(admin, server)
        context = browser.new_context(viewport={"width": VIEWPORT_W, "height": VIEWPORT_H})
        watcher = context.new_page()
        log_in(watcher, server, "watcher", "e2e-watcher-password")
        for screen in (admin, watcher):
            screen.get_by_test_id("nav-monitor").click()
            expect(screen.get_by_test_id("live-connection")).to_have_text("live")
            screen.evaluate(COUNT_BEEPS)
        admin.get_by_test_id("events-sound").check()  # the admin hears new events, the watcher does not

        def event_of(screen: Page, listing: str) -> Locator:
            return screen.get_by_test_id(listing).locator('[data-vehicle="silent-1"][data-kind="stale"]')

        # one position, then silence: the server opens a stale event and both screens show it, unacknowledged
        (frame,) = recorded_frames(localisation_drive(tiny_site_dir), 1)
        assert silent.post(2000.0, frame.data)["status"] == "processed"
        wait_ms = (STALE_AFTER_S + DEADLINE_S) * 1000
        for screen in (admin, watcher):
            expect(event_of(screen, "events-pending")).to_have_attribute("data-open", "true", timeout=wait_ms)
            expect(event_of(screen, "events-pending")).to_contain_text(
                re.compile(r"\b\d\d:\d\d:\d\d silent-1 stale")
            )

        expect(admin.locator("body")).to_have_attribute("data-beeps", re.compile(r"^[1-9]"))
        assert watcher.locator("body").get_attribute("data-beeps") == "0"

        # the control room's viewer acknowledges it; the admin's screen shows who did, without a reload
        event_of(watcher, "events-pending").get_by_test_id("event-ack").click()
        for screen in (watcher, admin):
            done = event_of(screen, "events-acknowledged")
            expect(done).to_have_attribute("data-acknowledged", "true")
            expect(done.get_by_test_id("event-acknowledged-by")).to_contain_text("watcher")
            expect(event_of(screen, "events-pending")).to_have_count(0)
        stored = server.api("GET", "/api/events", params={"kind": "stale", "unacknowledged": "false"}).json()
        (event,) = [e for e in stored["items"] if e["vehicle"] == "silent-1"]
        assert event["acknowledged_by"] == "watcher" and event["ended_at"] is None
        # where it happened: the vehicle's last position, on the event's row
        last = server.api("GET", f"/api/vehicles/{silent.id}/positions").json()[-1]
        assert (event["x"], event["y"]) == pytest.approx((last["x"], last["y"]))
        where = f"at E {event['x']:.1f} / N {event['y']:.1f}"
        expect(admin.get_by_test_id(f"event-row-{event['id']}")).to_have_attribute("title", where)

        # the vehicle reports again: its event ends ("back" and the time) on both screens, still acknowledged
        assert silent.post(2000.1, frame.data)["status"] == "processed"
        for screen in (admin, watcher):
            done = screen.get_by_test_id(f"event-row-{event['id']}")
            expect(done).to_have_attribute("data-open", "false")
            expect(done).to_contain_text(re.compile(r"back \d\d:\d\d:\d\d"))
            expect(done).to_have_attribute("data-acknowledged", "true")
        ended = server.api("GET", "/api/events", params={"vehicle": silent.id, "kind": "stale"}).json()
        assert next(e for e in ended["items"] if e["id"] == event["id"])["ended_at"] is not None
        screenshot(admin, "ui_events")

        # filters: another kind or another vehicle hides it, its own shows it
        row = admin.get_by_test_id(f"event-row-{event['id']}")
        admin.get_by_test_id("events-kind").select_option("lost")
        expect(row).to_have_count(0)
        admin.get_by_test_id("events-kind").select_option("stale")
        expect(row).to_be_visible()
        admin.get_by_test_id("events-vehicle").select_option(str(other.id))
        expect(row).to_have_count(0)
        admin.get_by_test_id("events-vehicle").select_option(str(silent.id))
        expect(row).to_be_visible()

        # the CSV export holds the filtered log: this event with its end and who acknowledged it
        with admin.expect_download() as saved:
            admin.get_by_test_id("events-csv").click()
        assert saved.value.suggested_filename == "events.csv"
        rows = list(csv.DictReader(io.StringIO(Path(saved.value.path()).read_text())))
        assert rows and {(r["vehicle"], r["kind"]) for r in rows} == {("silent-1", "stale")}, rows
        (exported,) = [r for r in rows if r["id"] == str(event["id"])]
        assert exported["ended_at"] and exported["acknowledged_by"] == "watcher", exported
        context.close()
        assert page.errors == []
