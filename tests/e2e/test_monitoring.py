"""Live monitoring in the browser: replaying a time range of a vehicle's history (speed, scrubber, follow),
the camera-obscured status and alert and the vehicle's latest frame, against a real ``driftmap serve``
(fixtures of ``conftest.py``).

Every wait polls the DOM or the API up to a deadline (Playwright's ``expect``); nothing sleeps for a fixed time.
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
from playwright.sync_api import Page, expect

from driftmap.core.obscurants import LEVELS, apply_level
from driftmap.formats.frame_images import decode_gray, encode_png
from tests.api.access_helpers import localisation_drive, recorded_frames
from tests.e2e.conftest import ADMIN_PASSWORD, PageWithLog, Server, screenshot

DEADLINE_S = 60.0
FRAME_PERIOD_S = 0.1
REPLAY_FRAMES = 40


def log_in(page: Page, server: Server) -> None:
    page.goto(f"{server.base}/")
    page.fill("#username", "admin")
    page.fill("#password", ADMIN_PASSWORD)
    page.click("button[type=submit]")
    expect(page.get_by_test_id("whoami")).to_contain_text("admin")


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
        for i, f in enumerate(frames):  # a drive clock in seconds: the inputs show plain seconds
            vehicle.post(500.0 + FRAME_PERIOD_S * i, f.data)
        p = page.page
        log_in(p, server)
        p.get_by_test_id("nav-monitor").click()
        p.get_by_test_id("vehicle-row-replay-2").click()
        expect(p.get_by_test_id("replay-to")).to_have_value("500.2")
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
        assert page.errors == []
