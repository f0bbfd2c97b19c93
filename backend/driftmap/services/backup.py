"""Backup and restore of an embedded (SQLite) installation: the database, the blob store, the signing key.

A backup is one tar file::

    driftmap-backup.json      manifest: format, created (UTC), schema revision, blob count
    driftmap.sqlite3          a consistent snapshot made with SQLite's online backup API
    secret_key                the login-token signing key, when the data dir keeps one
    blobs/<aa>/<bb>/<sha256>  every blob file

It is taken while the server and workers run. Blobs are content-addressed and never change, so the order
makes it consistent: every blob present is copied, then the database is snapshotted, then the blobs
created meanwhile are copied; every blob the snapshot names is in the archive unless it was deleted (its
site or drive deleted) between the snapshot and that second pass. The archive is written to a temporary
file beside the target and renamed when complete, with mode 0600 (it holds the signing key).

Restore unpacks into an empty data dir (refused otherwise: nothing is overwritten), checks the database
(``PRAGMA integrity_check``) and every blob's SHA-256 against its name, then moves the files in. A
PostgreSQL installation is backed up with PostgreSQL's own tools plus the blob folder
(``docs/operations.md``); both commands refuse it with that pointer.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import sqlite3
import tarfile
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from driftmap.config import Settings
from driftmap.errors import BadInputError, ConflictError

__all__ = ["BackupSummary", "backup", "restore"]

FORMAT = "driftmap-backup/1"
MANIFEST = "driftmap-backup.json"
DATABASE = "driftmap.sqlite3"
SECRET_KEY = "secret_key"


@dataclass(frozen=True)
class BackupSummary:
    """What a backup holds (or a restore put back)."""

    path: Path
    blobs: int
    bytes: int
    schema_revision: str | None

    def describe(self) -> str:
        return (
            f"{self.path}: database (schema {self.schema_revision or 'unknown'}) and {self.blobs} blobs, "
            f"{self.bytes / 1e6:.1f} MB"
        )


def _sqlite_path(settings: Settings) -> Path:
    url = settings.resolved_database_url()
    if not url.startswith("sqlite:///"):
        raise BadInputError(
            "backup and restore handle the embedded SQLite database only; back up PostgreSQL with pg_dump "
            "and the blob folder beside it (docs/operations.md, Backups)",
            field="DRIFTMAP_DATABASE_URL",
        )
    return Path(url.removeprefix("sqlite:///"))


def _blob_files(root: Path) -> Iterator[Path]:
    if root.is_dir():
        for path in sorted(root.glob("??/??/*")):
            if path.is_file() and not path.name.startswith(".tmp-"):
                yield path


def _schema_revision(db_file: Path) -> str | None:
    with sqlite3.connect(db_file) as conn:
        try:
            row = conn.execute("SELECT version_num FROM alembic_version").fetchone()
        except sqlite3.DatabaseError:
            return None
    return None if row is None else str(row[0])


def backup(settings: Settings, out: Path) -> BackupSummary:
    """Write a backup of the installation ``settings`` names to the tar file ``out`` (see the module doc).

    Raises:
        BadInputError: PostgreSQL configured, no database in the data dir, or ``out`` exists.
    """
    db_file = _sqlite_path(settings)
    if not db_file.is_file():
        raise BadInputError(f"no database to back up at {db_file}", field="data_dir")
    out = Path(out)
    if out.exists():
        raise BadInputError(f"{out} already exists; name a new file", field="out")
    out.parent.mkdir(parents=True, exist_ok=True)
    blob_root = settings.blob_dir
    fd, tmp_name = tempfile.mkstemp(dir=out.parent, prefix=f".{out.name}-", suffix=".tmp")
    os.close(fd)
    tmp = Path(tmp_name)
    os.chmod(tmp, 0o600)
    try:
        with tempfile.TemporaryDirectory(dir=out.parent) as work, tarfile.open(tmp, "w") as tar:
            copied: set[str] = set()

            def copy_blobs() -> None:
                for path in _blob_files(blob_root):
                    if path.name not in copied:
                        try:
                            tar.add(path, arcname=f"blobs/{path.relative_to(blob_root).as_posix()}")
                        except FileNotFoundError:
                            continue  # deleted meanwhile: so is every row naming it, or the snapshot misses it
                        copied.add(path.name)

            copy_blobs()
            snapshot = Path(work) / DATABASE
            with sqlite3.connect(db_file) as source, sqlite3.connect(snapshot) as target:
                source.backup(target)
            copy_blobs()
            tar.add(snapshot, arcname=DATABASE)
            key = Path(settings.data_dir) / SECRET_KEY
            if key.is_file():
                tar.add(key, arcname=SECRET_KEY)
            revision = _schema_revision(snapshot)
            manifest = {
                "format": FORMAT,
                "created": datetime.now(UTC).isoformat(timespec="seconds").replace("+00:00", "Z"),
                "schema_revision": revision,
                "blobs": len(copied),
            }
            data = json.dumps(manifest, indent=2).encode()
            info = tarfile.TarInfo(MANIFEST)
            info.size, info.mode = len(data), 0o600
            tar.addfile(info, io.BytesIO(data))
        os.replace(tmp, out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return BackupSummary(out, len(copied), out.stat().st_size, revision)


def _safe_members(tar: tarfile.TarFile, archive: Path) -> list[tarfile.TarInfo]:
    members = tar.getmembers()
    for m in members:
        parts = Path(m.name).parts
        if not (m.isfile() or m.isdir()) or m.name.startswith("/") or ".." in parts:
            raise BadInputError(f"{archive}: member {m.name!r} is not a plain file inside the archive")
    return members


def restore(settings: Settings, archive: Path) -> BackupSummary:
    """Restore the backup ``archive`` into the empty data dir ``settings`` names (see the module doc).

    Raises:
        BadInputError: not a driftmap backup, a damaged database or blob (named), PostgreSQL configured.
        ConflictError: the data dir already holds a database or blobs (nothing is overwritten).
    """
    db_file = _sqlite_path(settings)
    archive = Path(archive)
    if not archive.is_file():
        raise BadInputError(f"no backup file at {archive}", field="archive")
    data_dir = Path(settings.data_dir)
    if db_file.exists() or any(_blob_files(settings.blob_dir)):
        raise ConflictError(
            f"{data_dir} already holds a database or blobs; restore into an empty data dir "
            "(DRIFTMAP_DATA_DIR), nothing was changed"
        )
    data_dir.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=data_dir, prefix=".restore-") as work:
        staged = Path(work)
        try:
            with tarfile.open(archive, "r") as tar:
                members = _safe_members(tar, archive)
                tar.extractall(staged, members=members, filter="data")
        except (tarfile.TarError, EOFError) as exc:
            raise BadInputError(f"{archive}: not a readable tar file ({exc})", field="archive") from exc
        manifest = _read_manifest(staged / MANIFEST, archive)
        snapshot = staged / DATABASE
        _check_database(snapshot, archive)
        blobs = _check_blobs(staged / "blobs", archive)
        settings.blob_dir.mkdir(parents=True, exist_ok=True)
        for path in _blob_files(staged / "blobs"):
            target = settings.blob_dir / path.relative_to(staged / "blobs")
            target.parent.mkdir(parents=True, exist_ok=True)
            os.replace(path, target)
        if (staged / SECRET_KEY).is_file() and not (data_dir / SECRET_KEY).exists():
            os.replace(staged / SECRET_KEY, data_dir / SECRET_KEY)
        db_file.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(snapshot, db_file)  # last: a restore cut short leaves no database to serve from
    revision = manifest.get("schema_revision")
    return BackupSummary(
        archive, blobs, archive.stat().st_size, revision if isinstance(revision, str) else None
    )


def _read_manifest(path: Path, archive: Path) -> dict[str, object]:
    try:
        manifest = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise BadInputError(
            f"{archive}: no readable {MANIFEST}; not a driftmap backup", field="archive"
        ) from exc
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT:
        raise BadInputError(f"{archive}: {MANIFEST} is not format {FORMAT}", field="archive")
    return manifest


def _check_database(snapshot: Path, archive: Path) -> None:
    if not snapshot.is_file():
        raise BadInputError(f"{archive}: holds no {DATABASE}", field="archive")
    try:
        with sqlite3.connect(snapshot) as conn:
            verdict = conn.execute("PRAGMA integrity_check").fetchone()
    except sqlite3.DatabaseError as exc:
        raise BadInputError(
            f"{archive}: {DATABASE} is not an SQLite database ({exc})", field="archive"
        ) from exc
    if verdict is None or verdict[0] != "ok":
        raise BadInputError(f"{archive}: {DATABASE} fails its integrity check: {verdict}", field="archive")


def _check_blobs(root: Path, archive: Path) -> int:
    count = 0
    for path in _blob_files(root):
        digest = hashlib.sha256()
        with path.open("rb") as handle:
            for chunk in iter(lambda: handle.read(1 << 20), b""):
                digest.update(chunk)
        if digest.hexdigest() != path.name:
            raise BadInputError(f"{archive}: blob {path.name} does not match its content", field="archive")
        count += 1
    return count
