"""``driftmap camera save|profiles`` and ``driftmap drive import --profile|--calibration`` on a real SQLite store:
a drive folder imported with a stored camera profile carries that camera, not its own ``drive.json`` block."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from typer.testing import CliRunner

from driftmap.cli import app
from driftmap.config import Settings, get_settings
from driftmap.formats.drive_folder import write_drive_folder
from driftmap.formats.drive_json import camera_to_json
from driftmap.formats.frame_images import encode_png
from driftmap.formats.records import DriveMeta, FrameRow
from driftmap.services import drives as drive_service
from driftmap.services import sites as site_service
from driftmap.store.storage import Storage
from tests.cli.in_process import point_cli_at
from tests.core.odometry.test_scale_check import straight_frames
from tests.floor_frames import pinhole_camera

runner = CliRunner()


@pytest.fixture
def store(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, tiny_site_dir: Path) -> Iterator[Path]:
    """An empty data dir with one site made from the tiny site's plan; commands run against it."""
    point_cli_at(monkeypatch, Settings(data_dir=tmp_path / "data"))
    result = runner.invoke(app, ["site", "create", "mine", "--survey", str(tiny_site_dir / "survey.dxf")])
    assert result.exit_code == 0, result.output
    yield tmp_path
    get_settings.cache_clear()


def _drive(folder: Path, name: str) -> Path:
    """A five-frame drive folder recorded by the 320x240 test camera with a deliberately wrong ``k_x``."""
    own = dataclasses.replace(pinhole_camera(), k_x_m_per_px=0.5)
    frames = straight_frames(5)
    rows = [FrameRow(i, i * 0.1) for i in range(len(frames))]
    write_drive_folder(
        folder / name, DriveMeta(name, "mapping", 10.0, own), rows, [encode_png(f) for f in frames]
    )
    return folder / name


def _camera_file(path: Path, **changes: Any) -> Path:
    path.write_text(json.dumps({"camera": camera_to_json(dataclasses.replace(pinhole_camera(), **changes))}))
    return path


def _stored_camera(name: str) -> dict[str, Any]:
    """The camera block stored with drive ``name`` of the site."""
    storage = Storage.open(get_settings())
    try:
        with storage.db.session() as session:
            drive = drive_service.get_drive(session, site_service.get_site(session, "mine"), name)
            return dict(drive.camera)
    finally:
        storage.close()


def test_a_saved_profile_replaces_the_folders_camera(store: Path) -> None:
    saved = runner.invoke(app, ["camera", "save", "rear-lhd", str(_camera_file(store / "cam.json"))])
    assert saved.exit_code == 0 and "camera profile 'rear-lhd' saved" in saved.output, saved.output
    listed = runner.invoke(app, ["camera", "profiles"])
    assert listed.exit_code == 0 and "rear-lhd" in listed.output and "320x240" in listed.output
    result = runner.invoke(
        app, ["drive", "import", "mine", str(_drive(store, "d1")), "--profile", "rear-lhd"]
    )
    assert result.exit_code == 0, result.output
    assert _stored_camera("d1")["k_x"] == pytest.approx(pinhole_camera().k_x_m_per_px)


def test_a_calibration_file_replaces_the_folders_camera(store: Path) -> None:
    cam = _camera_file(store / "cam.json", k_x_m_per_px=0.0123)
    result = runner.invoke(
        app, ["drive", "import", "mine", str(_drive(store, "d2")), "--calibration", str(cam)]
    )
    assert result.exit_code == 0, result.output
    assert _stored_camera("d2")["k_x"] == pytest.approx(0.0123)


def test_a_camera_of_another_size_is_refused_and_nothing_stored(store: Path) -> None:
    cam = _camera_file(store / "big.json", width_px=640, height_px=480)
    result = runner.invoke(
        app, ["drive", "import", "mine", str(_drive(store, "d3")), "--calibration", str(cam)]
    )
    assert result.exit_code != 0 and "640x480" in result.output and "320x240" in result.output
    listed = runner.invoke(app, ["drive", "list", "mine"])
    assert "d3" not in listed.output


def test_unknown_profile_and_both_sources_are_refused(store: Path) -> None:
    folder = str(_drive(store, "d4"))
    unknown = runner.invoke(app, ["drive", "import", "mine", folder, "--profile", "nope"])
    assert unknown.exit_code != 0 and "no camera profile named 'nope'" in unknown.output
    runner.invoke(app, ["camera", "save", "p", str(_camera_file(store / "cam.json"))])
    both = runner.invoke(
        app, ["drive", "import", "mine", folder, "--profile", "p", "--calibration", str(store / "cam.json")]
    )
    assert both.exit_code != 0 and "not both" in both.output
