"""The distribution: every third-party import declared, migrations and the UI shipped as package data."""

from __future__ import annotations

import ast
import os
import re
import shutil
import site
import subprocess
import sys
import tomllib
import zipfile
from importlib import metadata
from pathlib import Path
from typing import Any

import httpx
import pytest
import yaml

from driftmap.api.app import ui_dir
from driftmap.store.db import MIGRATIONS_DIR
from tests.processes import free_port, stop, wait_healthy, wait_until

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "backend" / "driftmap"
SERVE_DEADLINE_S = 60.0  # the installed server answers its health check within this, seconds (a busy machine)


def _normalised(name: str) -> str:
    """A distribution name as PEP 503 compares them."""
    return re.sub(r"[-_.]+", "-", name).lower()


def declared_distributions() -> set[str]:
    """The distributions ``pyproject.toml`` makes driftmap depend on at run time."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    return {_normalised(re.split(r"[\s\[<>=!~;]", spec, maxsplit=1)[0]) for spec in project["dependencies"]}


def imported_modules() -> dict[str, Path]:
    """The top-level modules driftmap's sources import (absolute imports; first file that does), but the
    standard library and driftmap itself."""
    found: dict[str, Path] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names: list[str] = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            for name in names:
                top = name.split(".")[0]
                if top not in sys.stdlib_module_names and top not in ("driftmap", "__future__"):
                    found.setdefault(top, path.relative_to(ROOT))
    return found


class TestDependencies:
    def test_every_third_party_import_is_declared(self) -> None:
        declared = declared_distributions()
        providers = metadata.packages_distributions()
        modules = imported_modules()
        assert {"numpy", "scipy", "cv2", "fastapi"} <= set(modules)
        undeclared = {
            module: (str(where), providers.get(module))
            for module, where in modules.items()
            if not {_normalised(d) for d in providers.get(module, [])} & declared
        }
        assert not undeclared, (
            f"imported but not in pyproject.toml dependencies (module: file, installed as): {undeclared}"
        )


class TestLock:
    def test_every_dependency_is_pinned_and_the_image_uses_the_lock(self) -> None:
        pins = {}
        for line in (ROOT / "requirements.lock").read_text().splitlines():
            if line and not line.startswith("#"):
                name, _, version = line.partition("==")
                pins[_normalised(name)] = version
        assert all(pins.values()), "every line of requirements.lock is name==version"
        assert declared_distributions() <= set(pins), declared_distributions() - set(pins)
        dockerfile = (ROOT / "Dockerfile").read_text()
        assert "-c requirements.lock" in dockerfile and "FROM node:22-" in dockerfile


class TestCompose:
    """docker-compose.yml: every service that keeps running has a health check, and what waits on it waits for
    it to be healthy; the one-shot schema upgrade is waited for to succeed."""

    @pytest.fixture
    def services(self) -> dict[str, Any]:
        found: dict[str, Any] = yaml.safe_load((ROOT / "docker-compose.yml").read_text())["services"]
        return found

    def test_every_lasting_service_has_a_health_check(self, services: dict[str, Any]) -> None:
        assert {"postgres", "redis", "migrate", "api", "worker"} <= set(services)
        for name, service in services.items():
            if service.get("restart") == "no":  # a one-shot job: its exit status is its health
                assert name == "migrate" and service["command"] == ["driftmap", "db", "upgrade"]
                continue
            check = service.get("healthcheck") or {}
            assert check.get("test") and not check.get("disable"), f"{name} has no health check"

    def test_dependents_wait_for_health_or_success(self, services: dict[str, Any]) -> None:
        for name, service in services.items():
            for needed, how in (service.get("depends_on") or {}).items():
                wanted = "service_completed_successfully" if needed == "migrate" else "service_healthy"
                assert how == {"condition": wanted}, (name, needed)

    def test_api_and_worker_checks_ask_their_own_ports(self, services: dict[str, Any]) -> None:
        api, worker = services["api"], services["worker"]
        port = next(a.split("=")[1] for a in api["command"] if a.startswith("--port="))
        assert f"http://127.0.0.1:{port}/api/health" in " ".join(api["healthcheck"]["test"])
        metrics = next(a.split("=")[1] for a in worker["command"] if a.startswith("--metrics-port="))
        assert f"http://127.0.0.1:{metrics}/metrics" in " ".join(worker["healthcheck"]["test"])


class TestPackageData:
    def test_migrations_are_inside_the_package(self) -> None:
        assert MIGRATIONS_DIR.is_relative_to(PACKAGE) and (MIGRATIONS_DIR / "env.py").is_file()
        assert len(list((MIGRATIONS_DIR / "versions").glob("*.py"))) >= 1

    def test_the_ui_is_found_through_the_package(self) -> None:
        link = PACKAGE / "ui"
        assert link.is_symlink() and link.resolve() == (ROOT / "frontend" / "dist").resolve()
        found = ui_dir()
        assert found is None or (found / "index.html").is_file()


def _build_wheel(source: Path, out: Path) -> Path:
    """Build the wheel of the checkout copied to ``source`` into ``out`` (no network, no build isolation), with
    the first Python here that has setuptools and bdist_wheel (the dev venv's, else the system's)."""
    build = "import setuptools.build_meta as b, sys; print(b.build_wheel(sys.argv[1]))"
    failures: list[str] = []
    for python in dict.fromkeys(
        p for p in (sys.executable, shutil.which("python3"), "/usr/bin/python3") if p
    ):
        done = subprocess.run(
            [python, "-c", build, str(out)],
            cwd=source,
            capture_output=True,
            text=True,
            timeout=120,
            check=False,
        )
        if done.returncode == 0:
            return out / done.stdout.strip().splitlines()[-1]
        failures.append(f"{python}: {done.stderr.strip().splitlines()[-1:]}")
    pytest.skip(f"no Python here can build a wheel (pip install setuptools wheel): {failures}")


def _ui_dist() -> Path:
    """frontend/dist, built when missing (``make test`` has built it)."""
    dist = ROOT / "frontend" / "dist"
    if not (dist / "index.html").is_file():
        npm = shutil.which("npm")
        if npm is None:
            pytest.skip("frontend/dist is missing and npm is not installed: run `make frontend`")
        subprocess.run([npm, "run", "build"], cwd=ROOT / "frontend", check=True, capture_output=True)
    return dist


class TestWheel:
    def test_an_installed_wheel_migrates_and_serves_the_ui(self, tmp_path: Path) -> None:
        """Build the wheel, install it in a fresh venv outside the checkout (the dev venv's site-packages
        lent for the dependencies, without its editable driftmap), then ``db upgrade`` and ``serve``."""
        source = tmp_path / "src"
        ignore = shutil.ignore_patterns("__pycache__", "*.egg-info")
        shutil.copytree(ROOT / "backend", source / "backend", symlinks=True, ignore=ignore)
        shutil.copytree(_ui_dist(), source / "frontend" / "dist")
        for name in ("pyproject.toml", "README.md"):
            shutil.copy(ROOT / name, source / name)
        wheel = _build_wheel(source, tmp_path)
        with zipfile.ZipFile(wheel) as archive:
            names = set(archive.namelist())
        assert {"driftmap/ui/index.html", "driftmap/migrations/env.py"} <= names

        venv = tmp_path / "venv"
        subprocess.run(
            [sys._base_executable, "-m", "venv", "--without-pip", str(venv)], check=True, timeout=60
        )
        python = venv / "bin" / "python"
        own = subprocess.run(
            [python, "-c", "import sysconfig; print(sysconfig.get_path('purelib'))"],
            capture_output=True, text=True, check=True,
        ).stdout.strip()  # fmt: skip
        lent = [p for p in site.getsitepackages() if Path(p).is_dir()]
        (Path(own) / "dev-dependencies.pth").write_text(
            "\n".join(lent) + "\n"
        )  # plain paths: no .pth of theirs runs
        env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH" and not k.startswith("DRIFTMAP_")}
        env["DRIFTMAP_DATA_DIR"] = str(tmp_path / "data")
        pip = [
            python,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--no-index",
            "--force-reinstall",
            "--no-compile",
        ]
        subprocess.run([*pip, str(wheel)], cwd=tmp_path, env=env, check=True, timeout=120)

        where = subprocess.run(
            [python, "-c", "import driftmap; print(driftmap.__file__)"], cwd=tmp_path, env=env,
            capture_output=True, text=True, check=True,
        ).stdout.strip()  # fmt: skip
        assert Path(where).is_relative_to(Path(own)), where
        driftmap = venv / "bin" / "driftmap"
        upgraded = subprocess.run(
            [driftmap, "db", "upgrade"], cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120
        )
        assert upgraded.returncode == 0, upgraded.stderr

        port, log = free_port(), tmp_path / "serve.log"
        with log.open("wb") as sink:
            server = subprocess.Popen(
                [driftmap, "serve", "--port", str(port)], cwd=tmp_path, env=env, stdout=sink, stderr=sink
            )
        base = f"http://127.0.0.1:{port}"
        try:
            wait_healthy(server, base, log, SERVE_DEADLINE_S)
            page = httpx.get(f"{base}/", timeout=5.0)
            assert page.status_code == 200 and "<html" in page.text.lower()
            wait_until(  # the worker process reports a moment after the port answers
                lambda: httpx.get(f"{base}/api/health", timeout=5.0).json()["status"] == "ok",
                "health ok with its worker",
                SERVE_DEADLINE_S,
            )
        finally:
            stop(server)
