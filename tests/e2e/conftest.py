"""Browser end-to-end tests: a real ``driftmap serve`` on a free port with a copy of the built tiny site, and
Debian's chromium driven by Playwright (headless). Screenshots of each view go to ``tests/e2e/artifacts/``.

Skipped (with the reason) only when no chromium binary can be found; ``make test`` installs it first.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import httpx
import pytest
from playwright.sync_api import Browser, ConsoleMessage, Error, Page, sync_playwright

from tests.api.access_helpers import built_tiny_data, copy_data_to_new_database
from tests.processes import driftmap_env, start_server, stop

REPO = Path(__file__).resolve().parents[2]
FRONTEND = REPO / "frontend"
ARTIFACTS = Path(__file__).resolve().parent / "artifacts"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
START_DEADLINE_S = 120.0
STALE_AFTER_S = 4.0
ADMIN_PASSWORD = "e2e-admin-password"
VIEWPORT_W, VIEWPORT_H = 1366, 768  # a control-room screen


def chromium_path() -> str | None:
    """Debian's chromium, when installed."""
    found = shutil.which("chromium") or shutil.which("chromium-browser")
    if found:
        return found
    return "/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None


def ensure_frontend_built() -> None:
    """Build frontend/dist when it is missing (``make test`` has built it already)."""
    if (FRONTEND / "dist" / "index.html").exists():
        return
    npm = shutil.which("npm")
    if npm is None:
        pytest.fail("frontend/dist is missing and npm is not installed: run `make frontend`")
    if not (FRONTEND / "node_modules").is_dir():
        subprocess.run([npm, "ci", "--no-audit", "--no-fund"], cwd=FRONTEND, check=True)
    subprocess.run([npm, "run", "build"], cwd=FRONTEND, check=True)


@dataclass
class Server:
    """A running ``driftmap serve``: its base URL, environment and an admin's bearer header."""

    base: str
    env: dict[str, str]
    admin: dict[str, str]
    log: Path

    def api(
        self,
        method: str,
        path: str,
        *,
        token: str | None = None,
        headers: dict[str, str] | None = None,
        **kwargs: object,
    ) -> httpx.Response:
        """Call the API as the admin, or with ``token`` (e.g. a vehicle's)."""
        auth = {"Authorization": f"Bearer {token}"} if token else self.admin
        return httpx.request(  # type: ignore[arg-type]
            method, f"{self.base}{path}", headers={**auth, **(headers or {})}, timeout=60.0, **kwargs
        )


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path) -> Iterator[Server]:
    """``driftmap serve`` (no job worker) over a private copy of the tiny site with its FAST map."""
    if chromium_path() is None:  # skip before building anything
        pytest.skip("chromium is not installed (make test installs it with apt-get)")
    ensure_frontend_built()
    work = tmp_path_factory.mktemp("e2e")
    data, database_url = copy_data_to_new_database(
        built_tiny_data(tmp_path_factory.getbasetemp(), tiny_site_dir), work / "data"
    )
    env = driftmap_env(data, database_url, stale_after_s=str(STALE_AFTER_S))
    add_user(env, "admin", "admin", ADMIN_PASSWORD)
    with admin_server(env, work / "serve.log") as running:
        yield running


def add_user(env: dict[str, str], name: str, role: str, password: str) -> None:
    """``driftmap user add`` in the environment ``env`` (the server's data dir and database)."""
    added = subprocess.run(
        [sys.executable, "-m", "driftmap", "user", "add", name, "--role", role, "--password-stdin"],
        input=f"{password}\n".encode(),
        env=env,
        capture_output=True,
        check=False,
    )
    assert added.returncode == 0, added.stderr.decode()


@contextmanager
def admin_server(env: dict[str, str], log: Path) -> Iterator[Server]:
    """``driftmap serve`` (no job worker) in ``env``, logged in as the admin ``add_user`` made; stopped after."""
    process, base = start_server(env, log, "--no-worker", deadline_s=START_DEADLINE_S)
    try:
        login = httpx.post(f"{base}/api/auth/login", json={"username": "admin", "password": ADMIN_PASSWORD})
        assert login.status_code == 200, login.text
        yield Server(base, env, {"Authorization": f"Bearer {login.json()['access_token']}"}, log)
    finally:
        stop(process)


@pytest.fixture
def worker(server: Server) -> Iterator[subprocess.Popen[bytes]]:
    """A ``driftmap worker`` beside the server (same data dir and queue), for tests that run jobs."""
    with server.log.with_name("worker.log").open("ab") as sink:
        process = subprocess.Popen(
            [sys.executable, "-m", "driftmap", "worker", "--heartbeat", "1"],
            env=server.env,
            stdout=sink,
            stderr=sink,
        )
    try:
        yield process
    finally:
        stop(process)


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    """Headless Debian chromium through Playwright; skips when chromium cannot be found."""
    executable = chromium_path()
    if executable is None:
        pytest.skip("chromium is not installed (make test installs it with apt-get)")
    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=executable, headless=True, args=CHROMIUM_ARGS)
        yield launched
        launched.close()


@dataclass
class PageWithLog:
    """A browser page and what it wrote to the console (errors and uncaught exceptions)."""

    page: Page
    errors: list[str]


@pytest.fixture
def page(browser: Browser) -> Iterator[PageWithLog]:
    context = browser.new_context(viewport={"width": VIEWPORT_W, "height": VIEWPORT_H})
    new_page = context.new_page()
    new_page.set_default_timeout(30_000)
    errors: list[str] = []

    def on_console(message: ConsoleMessage) -> None:
        if message.type == "error":
            errors.append(message.text)

    def on_error(error: Error) -> None:
        errors.append(f"uncaught: {error}")

    new_page.on("console", on_console)
    new_page.on("pageerror", on_error)
    yield PageWithLog(new_page, errors)
    context.close()


def screenshot(page: Page, name: str) -> Path:
    """Save a screenshot of the page as a test artefact."""
    ARTIFACTS.mkdir(exist_ok=True)
    path = ARTIFACTS / f"{name}.png"
    page.screenshot(path=str(path))
    return path
