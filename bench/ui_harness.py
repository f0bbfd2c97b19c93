"""Shared harness of the browser benchmarks: the app served in-process, headless chromium, a synthetic plan.

:func:`ui_session` opens a fresh data dir (an admin user ``bench`` and an empty site ``grid``), serves the real
app (``create_app`` under uvicorn on a free loopback port, in a thread of this process so a benchmark can reach
its position hub) with the built ``frontend/dist``, logs in, and launches Debian's chromium through Playwright.
:func:`plan_dxf` draws the synthetic mine grid (see bench_ui.py's docstring). Used by bench/bench_ui.py.
"""

from __future__ import annotations

import argparse
import asyncio
import io
import itertools
import json
import math
import os
import shutil
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import ezdxf
import httpx
import numpy as np
import uvicorn
from ezdxf.document import Drawing
from playwright.sync_api import Browser, ConsoleMessage, Page, sync_playwright

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the tests' helpers

from tests.processes import free_port

from driftmap.api.app import create_app, ui_dir
from driftmap.config import Settings
from driftmap.services import sites as site_service
from driftmap.services import users as user_service
from driftmap.store.storage import Storage

PASSWORD = "bench-ui-password"
TOKEN_KEY = "driftmap_token"  # frontend/src/session.ts keeps the login token under this sessionStorage key
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
]
VIEWPORT = {"width": 1366, "height": 768}
SIDE_M = 2000.0
DRIFT_SPACING_M = 50.0
WALL_OFFSET_M = 2.5
NOISE_M = 0.05
ORIGIN = (13_000.0, 56_000.0)  # mine-grid easting/northing of the plan's corner

# Counts the live socket's position messages and records requestAnimationFrame intervals once started.
INIT_SCRIPT = """
(() => {
  const bench = (window.__bench = { positions: 0, frames: [], recording: false });
  const Native = window.WebSocket;
  window.WebSocket = class extends Native {
    constructor(...args) {
      super(...args);
      if (String(args[0]).includes("/api/live")) {
        this.addEventListener("message", (e) => {
          if (typeof e.data === "string" && JSON.parse(e.data).type === "position") bench.positions += 1;
        });
      }
    }
  };
  let last = null;
  const tick = (now) => {
    if (bench.recording && last !== null) bench.frames.push(now - last);
    last = now;
    requestAnimationFrame(tick);
  };
  requestAnimationFrame(tick);
})();
"""
START_RECORDING = "() => { window.__bench.frames = []; window.__bench.recording = true; }"
STOP_RECORDING = "() => { window.__bench.recording = false; return window.__bench.frames; }"


def plan_dxf(segments: int, seed: int = 0) -> tuple[bytes, int]:
    """A synthetic mine grid with about ``segments`` wall segments; returns (DXF bytes, exact segment count)."""
    rng = np.random.default_rng(seed)
    drifts = int(SIDE_M / DRIFT_SPACING_M) + 1
    walls = 2 * drifts * 2  # both directions, two walls per drift
    per_wall = max(1, round(segments / walls))
    doc: Drawing = ezdxf.new("R2010")  # type: ignore[attr-defined]
    doc.layers.add("WALLS")
    doc.layers.add("CENTRELINE")
    msp = doc.modelspace()
    count = 0
    x0, y0 = ORIGIN
    for direction in (0, 1):
        for k in range(drifts):
            at = k * DRIFT_SPACING_M
            along = np.linspace(0.0, SIDE_M, per_wall + 1)
            for offset in (-WALL_OFFSET_M, WALL_OFFSET_M):
                across = at + offset + rng.normal(0.0, NOISE_M, along.size)
                xs, ys = (along, across) if direction == 0 else (across, along)
                points = list(zip((xs + x0).tolist(), (ys + y0).tolist(), strict=True))
                if k % 2 == 0:
                    for a, b in itertools.pairwise(points):
                        msp.add_line(a, b, dxfattribs={"layer": "WALLS"})
                else:
                    msp.add_lwpolyline(points, dxfattribs={"layer": "WALLS"})
                count += per_wall
            ends = (
                [(x0, y0 + at), (x0 + SIDE_M, y0 + at)]
                if direction == 0
                else [(x0 + at, y0), (x0 + at, y0 + SIDE_M)]
            )
            msp.add_lwpolyline(ends, dxfattribs={"layer": "CENTRELINE"})
            count += 1
    stream = io.StringIO()
    doc.write(stream)
    return stream.getvalue().encode(), count


def renderer_query(args: argparse.Namespace) -> str:
    """The page URL's query choosing the survey renderer (empty: the app's own choice)."""
    return "" if args.renderer == "auto" else f"?renderer={args.renderer}"


class ServerThread:
    """The app served by uvicorn in a thread with its own event loop (reachable for hub publishes)."""

    def __init__(self, settings: Settings) -> None:
        self.app = create_app(settings)
        self.port = free_port()
        self.base = f"http://127.0.0.1:{self.port}"
        self.server = uvicorn.Server(
            uvicorn.Config(self.app, host="127.0.0.1", port=self.port, log_level="warning")
        )
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(
            target=self.loop.run_until_complete, args=(self.server.serve(),), daemon=True
        )

    def __enter__(self) -> ServerThread:
        self.thread.start()
        deadline = time.monotonic() + 120.0
        while not self.server.started:
            if time.monotonic() > deadline or not self.thread.is_alive():
                raise RuntimeError("the server did not start")
            time.sleep(0.05)
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.should_exit = True
        self.thread.join(30.0)


def percentile(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q)) if values else math.nan


def log_in_page(browser: Browser, base: str, token: str) -> Page:
    context = browser.new_context(viewport=VIEWPORT)  # type: ignore[arg-type]
    context.add_init_script(f"sessionStorage.setItem({json.dumps(TOKEN_KEY)}, {json.dumps(token)});")
    context.add_init_script(INIT_SCRIPT)
    page = context.new_page()
    page.set_default_timeout(120_000)
    return page


def console_errors(page: Page) -> list[str]:
    """The page's console errors, collected from now on."""
    errors: list[str] = []

    def on_console(message: ConsoleMessage) -> None:
        if message.type == "error":
            errors.append(message.text)

    page.on("console", on_console)
    return errors


def frame_stats(page: Page, seconds: float) -> list[float]:
    """requestAnimationFrame intervals (ms) of the page over the next ``seconds``."""
    page.evaluate(START_RECORDING)
    page.wait_for_timeout(seconds * 1000)
    frames: list[float] = page.evaluate(STOP_RECORDING)
    return frames


@dataclass
class UiSession:
    """What a benchmark drives: the served app, the browser, and the admin's login token."""

    server: ServerThread
    browser: Browser
    token: str

    @property
    def admin(self) -> dict[str, str]:
        """Request headers of the logged-in admin."""
        return {"Authorization": f"Bearer {self.token}"}


@contextmanager
def ui_session() -> Iterator[UiSession]:
    """A fresh data dir, the app serving it and a headless chromium (see the module docstring).

    Exits the process with a message when chromium or the built frontend is missing.
    """
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        sys.exit("chromium is not installed (apt-get install chromium)")
    if ui_dir() is None:
        sys.exit("frontend/dist is missing: cd frontend && npm run build")

    with tempfile.TemporaryDirectory(prefix="bench-ui-") as work:
        settings = Settings(data_dir=Path(work) / "data", live_processes=1, stale_after_s=30.0)
        storage = Storage.open(settings)
        with storage.db.session() as session:
            user_service.create_user(session, "bench", PASSWORD, "admin")
            site_service.create_site(session, "grid")
        storage.close()
        with ServerThread(settings) as server, sync_playwright() as playwright:
            login = httpx.post(
                f"{server.base}/api/auth/login", json={"username": "bench", "password": PASSWORD}
            )
            login.raise_for_status()
            token = login.json()["access_token"]
            browser = playwright.chromium.launch(executable_path=chromium, headless=True, args=CHROMIUM_ARGS)
            probe = browser.new_page()
            webgl = probe.evaluate(
                "() => { const gl = document.createElement('canvas').getContext('webgl2');"
                " if (!gl) return 'none'; const i = gl.getExtension('WEBGL_debug_renderer_info');"
                " return String(gl.getParameter(i ? i.UNMASKED_RENDERER_WEBGL : gl.RENDERER)); }"
            )
            probe.close()
            load = ", ".join(f"{v:.1f}" for v in os.getloadavg())
            print(
                f"headless chromium {browser.version}, WebGL: {webgl}; load average {load} on {os.cpu_count()} cores"
            )
            try:
                yield UiSession(server, browser, token)
            finally:
                browser.close()
