"""``driftmap backup`` and ``driftmap restore`` on a real SQLite data dir with a built map: a backup taken while
the API writes, restored into a fresh data dir, answers the API as the original did; refusals change nothing."""

from __future__ import annotations

import io
import tarfile
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from fastapi.testclient import TestClient
from typer.testing import CliRunner

from driftmap.api.app import create_app
from driftmap.cli import app
from driftmap.config import Settings, get_settings
from tests.api.access_helpers import built_tiny_data, copy_data
from tests.api.data_helpers import ApiUsers, api_users
from tests.cli.in_process import point_cli_at

runner = CliRunner()


@pytest.fixture
def serving(
    tmp_path_factory: pytest.TempPathFactory, tiny_site_dir: Path, tmp_path: Path
) -> Iterator[ApiUsers]:
    """An app with users of every role on a private copy of the built tiny site (embedded SQLite)."""
    data = copy_data(built_tiny_data(tmp_path_factory.getbasetemp(), tiny_site_dir), tmp_path / "data")
    users = api_users(Settings(data_dir=data))
    yield users
    users.client.close()


def _cli(monkeypatch: pytest.MonkeyPatch, data_dir: Path, *args: str) -> Any:
    point_cli_at(monkeypatch, Settings(data_dir=data_dir))
    try:
        return runner.invoke(app, list(args))
    finally:
        get_settings.cache_clear()


def _answers(users: ApiUsers) -> dict[str, Any]:
    """What a viewer sees of the tiny site: its drives, frames, maps and the map's contents."""
    site = next(s for s in users.get("/api/sites")["items"] if s["name"] == "tiny")
    sid = site["id"]
    drives = users.get(f"/api/sites/{sid}/drives")
    first = drives["items"][0]["id"]
    out = {
        "site": site,
        "drives": drives,
        "frames": users.get(f"/api/drives/{first}/frames"),
        "maps": users.get(f"/api/sites/{sid}/maps"),
        "map": users.get(f"/api/sites/{sid}/maps/1"),
        "poses": users.get(f"/api/sites/{sid}/maps/1/poses"),
        "nodes": users.get(f"/api/sites/{sid}/maps/1/nodes"),
        "survey": users.get(f"/api/sites/{sid}/survey"),
    }
    image = users.client.get(f"/api/drives/{first}/frames/0", headers=users.auth("viewer"))
    assert image.status_code == 200, image.text
    out["frame_bytes"] = image.content  # a blob read back
    return out


def test_a_backup_taken_while_serving_restores_to_the_same_answers(
    serving: ApiUsers, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    data = Path(serving.app.state.settings.data_dir)
    before = _answers(serving)
    stop, created = threading.Event(), []

    def write() -> None:  # the API keeps writing while the backup runs
        while not stop.is_set():
            name = f"new-{len(created)}"
            r = serving.client.post("/api/sites", json={"name": name}, headers=serving.auth("admin"))
            assert r.status_code == 201, r.text
            created.append(name)

    writer = threading.Thread(target=write)
    writer.start()
    try:
        result = _cli(monkeypatch, data, "backup", str(tmp_path / "site.tar"))
    finally:
        stop.set()
        writer.join()
    assert result.exit_code == 0, result.output
    assert created, "the writer made no site while the backup ran"
    with tarfile.open(tmp_path / "site.tar") as tar:
        names = tar.getnames()
    assert {"driftmap-backup.json", "driftmap.sqlite3", "secret_key"} <= set(names)
    assert (tmp_path / "site.tar").stat().st_mode & 0o077 == 0  # it holds the signing key

    fresh = tmp_path / "fresh"
    result = _cli(monkeypatch, fresh, "restore", str(tmp_path / "site.tar"))
    assert result.exit_code == 0, result.output
    restored = api_users_on(fresh, serving)
    assert _answers(restored) == before
    sites = restored.get("/api/sites", params={"limit": 500})
    names = [s["name"] for s in sites["items"]]
    assert sites["total"] == len(names) and set(names) - {"tiny"} <= set(created)  # the writes up to a moment


def api_users_on(data_dir: Path, original: ApiUsers) -> ApiUsers:
    """An app on the restored ``data_dir`` used with the original's tokens (the signing key came back too)."""
    restored = create_app(Settings(data_dir=data_dir))
    return ApiUsers(restored, TestClient(restored), dict(original.tokens))


class TestRefusals:
    def test_restore_into_a_data_dir_in_use_changes_nothing(
        self, serving: ApiUsers, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        data = Path(serving.app.state.settings.data_dir)
        assert _cli(monkeypatch, data, "backup", str(tmp_path / "a.tar")).exit_code == 0
        db = data / "driftmap.sqlite3"
        stamp = db.stat().st_mtime_ns, db.stat().st_size
        result = _cli(monkeypatch, data, "restore", str(tmp_path / "a.tar"))
        assert result.exit_code != 0 and "already holds a database" in result.output
        assert (db.stat().st_mtime_ns, db.stat().st_size) == stamp

    def test_backup_over_an_existing_file_is_refused(
        self, serving: ApiUsers, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        data = Path(serving.app.state.settings.data_dir)
        target = tmp_path / "kept.tar"
        target.write_text("mine")
        result = _cli(monkeypatch, data, "backup", str(target))
        assert result.exit_code != 0 and "already exists" in result.output
        assert target.read_text() == "mine"

    def test_a_damaged_blob_is_named_and_nothing_is_restored(
        self, serving: ApiUsers, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        data = Path(serving.app.state.settings.data_dir)
        assert _cli(monkeypatch, data, "backup", str(tmp_path / "a.tar")).exit_code == 0
        damaged, bad = tmp_path / "damaged.tar", ""
        with tarfile.open(tmp_path / "a.tar") as src, tarfile.open(damaged, "w") as dst:
            for member in src.getmembers():
                payload = src.extractfile(member)
                if not bad and member.name.startswith("blobs/") and payload is not None:
                    bad = Path(member.name).name
                    content = b"not the blob" + payload.read()
                    member.size = len(content)
                    dst.addfile(member, io.BytesIO(content))
                else:
                    dst.addfile(member, payload)
        fresh = tmp_path / "fresh"
        result = _cli(monkeypatch, fresh, "restore", str(damaged))
        assert result.exit_code != 0 and bad in result.output
        assert not (fresh / "driftmap.sqlite3").exists()
        assert not list(fresh.glob("blobs/??/??/*"))

    def test_a_file_that_is_not_a_backup_is_named(
        self, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
    ) -> None:
        junk = tmp_path / "junk.tar"
        junk.write_bytes(b"\x00" * 2048)
        result = _cli(monkeypatch, tmp_path / "fresh", "restore", str(junk))
        assert result.exit_code != 0 and "junk.tar" in result.output
        assert not (tmp_path / "fresh" / "driftmap.sqlite3").exists()
